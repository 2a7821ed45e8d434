import os

os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("DRAKE_EST_NO_PROGRESS", "1")

import matplotlib  # noqa: E402

matplotlib.use("Agg")
