"""The hinge method's right-hand side transcribed from heyoka's decomposition, for other integrators.

A peer integrator must integrate the *same* equations as ``method="hinges"``: the
Baumgarte-stabilised multiplier equations of :class:`linkage.constraints.ChainSystem`,
``x' = v``, ``v' = K^-1 G^T M^-1 r`` (:meth:`manifold.constrained.ConstrainedPieces.equations`).
Rather than writing them a second time, this module reads the decomposition of the
library's compiled acceleration (``CompiledConstrained.acceleration(float).dc``: one
elementary operation per entry, ``u_k = u_i * u_j``, ``sub(u_i, u_j)``, ``div(u_i, u_j)``,
``-u_i``, parameters ``p_k``) and writes it out as straight-line Python source, one
assignment per entry.  That source runs as it is under numba (``numba.njit``) and under
JAX (``jax.jit``: the array indexing and ``stack`` are the only array operations).

The transcription is checked against the heyoka function at random states by
``tests/test_peers.py``.
"""

from __future__ import annotations

import ast
from collections.abc import Callable
from typing import Any

import numpy as np

from linkage import Chain
from linkage.constraints import ChainSystem
from manifold.constrained import ConstrainedGeometry, compiled_constrained

#: heyoka's binary functions in a decomposition, as Python operators
_BINARY = {"sub": ast.Sub(), "div": ast.Div()}


class _ToPython(ast.NodeTransformer):
    """``sub(a, b)`` -> ``a - b``, ``div(a, b)`` -> ``a / b``, ``p7`` -> ``p[7]``; anything else is refused."""

    def visit_Call(self, node: ast.Call) -> ast.AST:
        name = node.func.id if isinstance(node.func, ast.Name) else None
        if name not in _BINARY or len(node.args) != 2 or node.keywords:
            raise ValueError(f"no transcription for heyoka function {ast.unparse(node)!r}")
        left, right = (self.visit(arg) for arg in node.args)
        return ast.BinOp(left, _BINARY[name], right)

    def visit_Name(self, node: ast.Name) -> ast.AST:
        if node.id.startswith("p") and node.id[1:].isdigit():
            return ast.Subscript(ast.Name("p", ast.Load()), ast.Constant(int(node.id[1:])), ast.Load())
        if node.id.startswith("u_") and node.id[2:].isdigit():
            return node
        raise ValueError(f"unexpected name {node.id!r} in a decomposition")


def rhs_source(cfunc: Any, name: str = "rhs", stack: str = "stack") -> str:
    """Python source of ``def name(y, p)``: ``(v, cfunc(y, p))`` for a cfunc of ``y = (x, v)``, ``len(x) = len(v)``.

    ``stack`` names the function that builds the output array from a list of scalars
    (``numpy.array`` under numba, ``jax.numpy.stack`` under JAX).
    """
    dc = [str(e) for e in cfunc.dc]
    n_vars, n_out = cfunc.nvars, cfunc.nouts
    if n_vars != 2 * n_out:
        raise ValueError(f"expected a function of (x, v) giving x'' (2 N inputs, N outputs), got {n_vars} and {n_out}")
    lines = [f"def {name}(y, p):"]
    lines += [f"    u_{k} = y[{k}]" for k in range(n_vars)]
    for k, text in enumerate(dc[n_vars : len(dc) - n_out], start=n_vars):
        tree = _ToPython().visit(ast.parse(text, mode="eval"))
        lines.append(f"    u_{k} = {ast.unparse(tree.body)}")
    outs = [f"u_{k}" for k in range(n_out, n_vars)]  # x' = v
    outs += [ast.unparse(_ToPython().visit(ast.parse(text, mode="eval")).body) for text in dc[-n_out:]]
    lines.append(f"    return {stack}([{', '.join(outs)}])")
    return "\n".join(lines) + "\n"


def hinge_rhs(chain: Chain, stack: Callable[..., Any] = np.array) -> Callable[[Any, Any], Any]:
    """``f(y, p) = (v, x'')``, the hinge method's equations as plain Python (wrap it in ``numba.njit`` or ``jax.jit``)."""
    source = rhs_source(compiled_constrained(ChainSystem(chain)).acceleration(float))
    namespace: dict[str, Any] = {"stack": stack}
    exec(compile(source, f"<hinge equations, n = {chain.n}>", "exec"), namespace)
    return namespace["rhs"]


def hinge_start(chain: Chain, h0: Any, w0: Any, t_final: float) -> tuple[np.ndarray, np.ndarray]:
    """The state ``y0 = (x0, v0)`` and parameters the hinge method starts from (its projection, its Baumgarte rate).

    :meth:`manifold.constrained.ConstrainedGeometry.start` is what ``solve_constrained`` calls, so the peers
    start from the hinge method's own float64 start and integrate with its damping rate ``alpha``.
    """
    system = ChainSystem(chain)
    geo = ConstrainedGeometry(system, float)
    xs, vs, _, alphas = geo.start(chain.to_point(np.asarray(h0))[None, :], chain.to_point(np.asarray(w0))[None, :],
                                  t_final, 1.0)
    comp = compiled_constrained(system)
    pars = comp.layout.pack(system, float(alphas[0]), float)[: comp.acceleration(float).nparams]
    return np.concatenate([xs[0], vs[0]]).astype(float), np.asarray(pars, dtype=float)
