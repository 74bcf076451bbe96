"""Units of work of a fleet and their grouping into tasks.

Tasks are sized to about ``target_task_bytes`` of input (4 MiB; a 30 min, 100 Hz CSV.gz
log is 7 MB, a task of its own; longest first onto the lightest task), with at least 4
tasks per worker when there are enough units (:func:`plan_tasks`); with channel splits
and fewer units than workers, long logs are split by channel (:func:`plan_work`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["plan_tasks", "plan_work"]


def plan_tasks(
    sizes: Sequence[int], n_workers: int, target_task_bytes: int = 4 << 20
) -> list[list[int]]:
    """Group units (by index) into tasks of about ``target_task_bytes`` each.

    At least ``min(len(sizes), 4 * n_workers)`` tasks, so that every worker
    has work, and a multiple of ``n_workers`` when there are units enough (16
    equal units on 2 workers: 16 tasks, not 15 with one of two units that the
    other worker waits for); longest-processing-time-first assignment.
    """
    n = len(sizes)
    if n == 0:
        return []
    total = int(sum(sizes))
    w = max(1, n_workers)
    k = max(math.ceil(total / max(1, target_task_bytes)), min(n, 4 * w))
    k = min(math.ceil(k / w) * w, n)
    loads = [0] * k
    tasks: list[list[int]] = [[] for _ in range(k)]
    for i in sorted(range(n), key=lambda i: -sizes[i]):
        j = min(range(k), key=lambda j: loads[j])
        tasks[j].append(i)
        loads[j] += int(sizes[i])
    return [sorted(t) for t in tasks if t]


def plan_work(
    sizes: Sequence[int], n_workers: int, min_split_bytes: int = 4 << 20
) -> list[tuple[int, tuple[int, int] | None]]:
    """Units of work: ``(unit index, channel part)``; a unit whole (part ``None``) or,
    when there are fewer units than workers, a log of at least ``min_split_bytes`` split
    by channel into ``(i, n)`` parts (n of 2, 3 or 6 contiguous slices of the six IMU
    channels, the fewest that give every worker a part).

    Each part reads the whole log again (reading a CSV.gz is about 40 % of a unit's
    time), so a split pays only when workers would otherwise be idle: 3 units on 2
    workers are not split (6 parts would read 6 logs for 3 units' analysis)."""
    n = len(sizes)
    w = max(1, n_workers)
    items: list[tuple[int, tuple[int, int] | None]] = []
    for i, size in enumerate(sizes):
        parts = 1
        if 0 < n < w and size >= min_split_bytes:
            parts = next((k for k in (2, 3, 6) if k >= math.ceil(w / n)), 6)
        if parts == 1:
            items.append((i, None))
        else:
            items.extend((i, (j, parts)) for j in range(parts))
    return items
