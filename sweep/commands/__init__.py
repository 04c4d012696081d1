"""What the CLI's commands do besides running a sweep: audit, extend, trace and the paper's
figures.
"""
