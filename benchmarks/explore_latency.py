"""What the explorer's server adds to a solve: ``POST /api/motion`` of T = 10 at n = 4 against ``free_motion``.

``python -m benchmarks.explore_latency`` starts the server on a free port of this machine, and for three starts
interleaves, ``--repeats`` times each: the request's wall time seen by a client (httpx; validation, the solve in
a worker thread, the chart-0 sphere points and rod angles of 201 samples, JSON both ways), and the same
``free_motion`` called directly with the same sample grid (wall time).  It prints the minimum and the median of
each and their ratio, for both methods.
"""

from __future__ import annotations

import argparse
import statistics
import time

import httpx
import numpy as np

from linkage import Chain
from linkage.explore.cli import serve_in_thread
from linkage.explore.protocol import as_pairs
from linkage.motion import free_motion
from linkage.sampling import sample_starts
from manifold import SaveAt


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15)
    args = parser.parse_args()
    chain = Chain(4, 3.0)
    H, V = sample_starts(chain, 3, 0.5, np.random.default_rng(0))
    times = np.linspace(0.0, 10.0, 201)
    with serve_in_thread(4, 3.0) as url, httpx.Client(base_url=url, timeout=60) as http:
        for method in ("charts", "hinges"):
            api, direct = [], []
            for k in range(len(H)):  # warm up: compiles (heyoka caches them on disk) and first calls
                free_motion(chain, H[k], V[k], 10.0, method=method, save=SaveAt(t_eval=times))
            for _ in range(args.repeats):
                for k in range(len(H)):
                    body = {"lengths": 4, "L": 3.0, "hinges": as_pairs(H[k]), "velocity": as_pairs(V[k]),
                            "T": 10.0, "samples": 201, "method": method}
                    t0 = time.perf_counter()
                    answer = http.post("/api/motion", json=body)
                    api.append(time.perf_counter() - t0)
                    assert answer.status_code == 200, answer.text
                    t0 = time.perf_counter()
                    free_motion(chain, H[k], V[k], 10.0, method=method, save=SaveAt(t_eval=times))
                    direct.append(time.perf_counter() - t0)
            print(f"{method:7s} POST /api/motion T = 10, n = 4, 201 samples: min {1e3 * min(api):6.1f} ms, "
                  f"median {1e3 * statistics.median(api):6.1f} ms | free_motion alone: min {1e3 * min(direct):6.1f} "
                  f"ms, median {1e3 * statistics.median(direct):6.1f} ms | ratio of minima "
                  f"{min(api) / min(direct):.2f}")


if __name__ == "__main__":
    main()
