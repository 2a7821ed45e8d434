import os

# small per-step linear algebra is faster single-threaded on shared 2-core machines (shared/drake_notes.md)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("DRAKE_EST_NO_PROGRESS", "1")

import matplotlib  # noqa: E402

matplotlib.use("Agg")
