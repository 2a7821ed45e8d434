"""Loaders for real measured data sets (read from a user-given folder, default ../shared/data)."""
