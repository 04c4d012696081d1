"""Result datasets in memory: the Dataset built from the kernels' arrays, its checks, and
statistics of slip-event catalogues and over realisations of the disorder.
"""
