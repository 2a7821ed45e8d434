"""Profile the diagnosis of one closed-loop log of the speed benchmark (cProfile, one thread).

    OPENBLAS_NUM_THREADS=1 python benchmarks/profile_diagnose_speed_log.py [SEED]   # default 4, the slowest

Generates the log with ``bench_diagnose_speed.loop_log`` (45,000 samples at 100 Hz, the pair of effects of that seed),
diagnoses it without re-simulation on one thread and prints the named effects and the 40 most costly calls, by
cumulative and by own time.
"""
from __future__ import annotations

import cProfile
import os
import pstats
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_diagnose_speed as S  # noqa: E402


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        seed = int(argv[0]) if argv else 4
    except ValueError:
        raise SystemExit(f"expected a seed (an integer), got {argv[0]!r}")
    from drake_est.diagnose import diagnose
    effs, lg = S.loop_log(seed)
    pr = cProfile.Profile()
    pr.enable()
    rep = diagnose(lg, robot="generic", seed=0, simulate=False, threads=1)
    pr.disable()
    print(f"closed-loop log {'+'.join(effs)} seed {seed}: {rep.effects}")
    st = pstats.Stats(pr)
    st.sort_stats("cumulative").print_stats(40)
    st.sort_stats("tottime").print_stats(40)


if __name__ == "__main__":
    main()
