"""Adaptive refinement: the lattice of refined points, the refined (point-wise) Dataset and
the boundaries between its labels and their types.
"""
