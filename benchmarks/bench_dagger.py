"""DAgger's training step on one process and on several: seconds, speed-up, the same numbers.

Run:  python benchmarks/bench_dagger.py [--network NAME] [--episodes N] [--iterations K]
      [--processes 1,2] [--code compiled,numpy] [--repeats R]

What ``stumble reflex fit --closed-loop`` spends most of its time on: L-BFGS
(``dagger.train_on``) over the identification's data and every pass's labelled episodes.
The data here has the shape of DAgger's last pass (``--episodes`` 32: 8 passes of 4
episodes of 8 s at 1 kHz, both legs, each leg a set) with standardised random inputs and
labels, on the shipped network's structure; ``--iterations`` L-BFGS iterations from its
weights. With P > 1 the sets are spread over P processes (``dagger.SetPool``). Prints,
per process count, the best of ``--repeats`` wall times, the speed-up over one process,
and whether the trained weights are the one-process weights bit for bit (they must be).
There is no MuJoCo in this step, so no bare-loop ratio: the figure is against one
process. ``--code``: the batch pass compiled (``kernels.batch_z`` and ``batch_dh``, with
Numba) or NumPy's (``STUMBLE_KERNELS=numpy``); each row says whether its weights are the
first row's bit for bit. The load average is printed too: other work on the machine
lowers the figures.
``--spin`` leaves OpenBLAS's idle threads spinning (its default), as in a process that
imported NumPy before stumble: then two processes train no faster than one.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

# what OpenBLAS reads when NumPy loads it (``import stumble`` sets it, but after NumPy here)
if "--spin" not in sys.argv:
    TIMEOUT = os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "4")
else:
    TIMEOUT = os.environ.get("OPENBLAS_THREAD_TIMEOUT", "unset")

import numpy as np

from stumble.control.reflex import kernels
from stumble.control.reflex.dagger import EPISODE_S, SetPool, train_on
from stumble.control.reflex.identify import default_network


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--network", default="placement")
    ap.add_argument("--episodes", type=int, default=32)
    ap.add_argument("--iterations", type=int, default=20)
    ap.add_argument("--processes", default="1,2", help="comma-separated process counts")
    ap.add_argument("--code", default="compiled,numpy",
                    help="comma-separated: compiled (Numba's batch pass), numpy")
    ap.add_argument("--repeats", type=int, default=2, help="best of this many (default 2)")
    ap.add_argument("--spin", action="store_true",
                    help="leave OpenBLAS's idle threads spinning (its own default)")
    args = ap.parse_args()
    net = default_network(args.network)
    n_in, nm = net.w.shape[0], net.topology.n_muscles
    ticks = round(EPISODE_S * net.topology.rate_hz)
    rng = np.random.default_rng(0)
    data = []
    for _ in range(args.episodes):
        x = rng.standard_normal((ticks, 2, n_in))
        y = rng.uniform(0.01, 0.99, (ticks, 2, nm))
        w = (rng.random(ticks) > 0.05).astype(float)
        data += [(x[:, side], y[:, side], w) for side in range(2)]
    print(f"{len(data)} sets of {ticks} ticks, {args.iterations} L-BFGS iterations, "
          f"OPENBLAS_THREAD_TIMEOUT {TIMEOUT}, "
          f"load average {os.getloadavg()[0]:.2f}")
    ref = None
    for code in args.code.split(","):
        if code not in ("compiled", "numpy"):
            sys.exit(f"bench_dagger: --code {code!r}: compiled or numpy")
        # the pool's workers inherit either: forked, the switch; spawned, the environment
        if code == "numpy":
            os.environ[kernels.ENV] = "numpy"
        else:
            os.environ.pop(kernels.ENV, None)
        kernels.use_numpy(code == "numpy")
        if code == "compiled" and kernels.kernels() is None:
            print("compiled: the kernels are off (no Numba, or they failed to compile); "
                  "skipped")
            continue
        for p in (int(v) for v in args.processes.split(",")):
            pool = SetPool(p) if p > 1 else None
            try:
                best = np.inf
                for _ in range(args.repeats):
                    tic = time.perf_counter()
                    trained, _loss = train_on(net, data, args.iterations, pool=pool)
                    best = min(best, time.perf_counter() - tic)
            finally:
                if pool is not None:
                    pool.close()
            if ref is None:
                ref = (best, trained.pack())
            same = np.array_equal(trained.pack(), ref[1])
            print(f"{code}, {p} process(es): {best:.2f} s, {ref[0] / best:.2f}x the first "
                  f"row, weights {'the same bit for bit' if same else 'DIFFERENT'}")


if __name__ == "__main__":
    main()
