"""How the bake's stages share the cores: rows of work on a thread per core, and work items
sized for the allocator."""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

from .process_tuning import blas_on_one_thread

# A bake's progress callback: (stage, fraction of the stage done).
Progress = Callable[[str, float], None]


def workers() -> int:
    return max(1, min(os.cpu_count() or 1, 8))


def parallel_rows(function, count: int, progress: Progress, stage: str):
    """Run function(i) for i in range(count) on all cores (numpy releases the GIL in its
    loops), reporting progress in completion order."""
    with blas_on_one_thread(), ThreadPoolExecutor(workers()) as pool:
        try:
            for done, _ in enumerate(pool.map(function, range(count)), 1):
                progress(stage, done / count)
        except BaseException:
            # A progress callback may stop the bake (a newer bake superseded it): drop the
            # rows not started rather than finishing the stage.
            pool.shutdown(wait=True, cancel_futures=True)
            raise


# Work items stay below ~32 MB per temporary array: larger ones are mmapped afresh by malloc
# on every allocation and page faults then cost more than the arithmetic.
LOOKUPS_PER_BATCH = 1 << 18


def ray_batches(n_h: int, n_a: int, lookups_per_ray: int):
    """(height index, slice of view rays) work items of about LOOKUPS_PER_BATCH look-ups."""
    rays = max(1, min(n_a, LOOKUPS_PER_BATCH // max(1, lookups_per_ray)))
    return [(i, slice(a, min(a + rays, n_a))) for i in range(n_h) for a in range(0, n_a, rays)]
