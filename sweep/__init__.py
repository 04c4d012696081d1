"""rsf-sweep: JIT-compiled parameter sweeps of the Rice–Ruina spring-block model.

Importing the package compiles nothing; kernels compile on first use.

    from sweep.config import load_config
    from sweep.runner import run_sweep
    result = run_sweep(load_config("configs/quick.yaml"))
"""

__version__ = "0.1.0"
