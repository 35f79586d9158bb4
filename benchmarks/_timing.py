"""Median CPU time of repeated calls, for the benchmark scripts."""

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
