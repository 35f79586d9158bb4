"""Measurements shared by the benchmark scripts: the median CPU time of
repeated calls and the resident memory of the process."""

import time

import numpy as np


def median_cpu(fun, repeat):
    """Median CPU seconds (``time.process_time``) of ``repeat`` calls of
    ``fun`` and the result of the last call."""
    times, out = [], None
    for _ in range(repeat):
        start = time.process_time()
        out = fun()
        times.append(time.process_time() - start)
    return float(np.median(times)), out


def resident_mb(key="VmHWM"):
    """Peak (``VmHWM``) or current (``VmRSS``) resident memory of this
    process in MB, from ``/proc/self/status`` (NaN where it has none)."""
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith(key + ":"):
                return int(line.split()[1]) / 1024
    return float("nan")
