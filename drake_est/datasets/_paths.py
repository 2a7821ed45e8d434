"""Deprecated name of :mod:`drake_est.datasets.paths` (kept for old imports)."""
from drake_est.datasets.paths import data_dir, data_file, default_data_dir  # noqa: F401
