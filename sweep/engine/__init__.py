"""Running sweeps: the grid, the compiled kernels it needs, where chunks run (threads,
Dask), and the uniform and refined runners.
"""
