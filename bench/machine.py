"""Machine description printed by every benchmark (CPU model, cores, Python, numba)."""

from __future__ import annotations

import os
import platform
import subprocess


def machine() -> str:
    """CPU model (lscpu), core count, Python and numba versions."""
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, check=True).stdout
        model = next(line.split(":", 1)[1].strip() for line in out.splitlines()
                     if line.startswith("Model name"))
    except (OSError, subprocess.CalledProcessError, StopIteration):
        model = platform.processor() or "unknown CPU"
    import numba

    return (f"{model}, {os.cpu_count()} cores, Python {platform.python_version()}, "
            f"numba {numba.__version__}")
