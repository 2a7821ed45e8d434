"""Fleet-scale diagnosis on Dask."""
