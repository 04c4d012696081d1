"""The physics: the rate-and-state model's parameters and equations in dimensionless form,
its linear stability theory, and per-block heterogeneity.
"""
