"""Files: atomic writes and locks, part files of unfinished sweeps, NetCDF and Zarr
results.
"""
