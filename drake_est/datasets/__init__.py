"""Loaders for real measured data sets (read from a user-given folder, default ../shared/data).

``data_dir()`` / ``data_file()`` / ``default_data_dir()`` resolve that folder (see :mod:`drake_est.datasets.paths`)."""
from drake_est.datasets.paths import data_dir, data_file, default_data_dir  # noqa: F401
