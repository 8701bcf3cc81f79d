"""Results of a long study written task by task, so that a cut run resumes where it stopped.

A :class:`TaskStore` is a folder with one JSON file per finished task (``tasks/<key>.json``, written
atomically: a file is either complete or absent, never half-written). A task is anything with a ``key``
attribute (a file-name-safe string that changes with every field the result depends on, e.g.
:attr:`gaitlog.host.studies.sweep_grid.SweepTask.key`). Runners (:func:`run_serial`, :func:`gaitlog.host.studies.dask_runner.run_on_dask`)
compute only the tasks whose file is missing and write each result as it arrives; :meth:`TaskStore.collect`
reads them back in the tasks' order, so the assembled results do not depend on which process finished first.

JSON keeps floats exactly (``repr`` round-trips), so a result read back equals the one computed.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from gaitlog.host.errors import HostError
from gaitlog.atomic_write import atomic_write_text

__all__ = ["TaskStore", "run_serial"]


class TaskStore:
    """One JSON file per finished task under ``folder/tasks`` (module notes)."""

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        self.tasks_folder = self.folder / "tasks"

    def path(self, task: Any) -> Path:
        """Where ``task``'s result is (or will be) stored."""
        return self.tasks_folder / f"{task.key}.json"

    def done(self, task: Any) -> bool:
        """True when ``task``'s result is stored."""
        return self.path(task).is_file()

    def pending(self, tasks: Sequence[Any]) -> list[Any]:
        """The tasks without a stored result, in order."""
        return [t for t in tasks if not self.done(t)]

    def write(self, task: Any, result: Any) -> None:
        """Store ``task``'s JSON-able ``result`` (atomically)."""
        self.tasks_folder.mkdir(parents=True, exist_ok=True)
        atomic_write_text(self.path(task), json.dumps(result, sort_keys=True))

    def read(self, task: Any) -> Any:
        """``task``'s stored result."""
        p = self.path(task)
        try:
            return json.loads(p.read_text(encoding="utf-8"))
        except OSError as err:
            raise HostError(f"{p}: cannot read a stored task result: {err.strerror or err}") from None
        except json.JSONDecodeError as err:
            raise HostError(f"{p}: damaged task result ({err}): delete it to recompute the task") from None

    def collect(self, tasks: Sequence[Any]) -> list[Any]:
        """Every task's stored result, in the order of ``tasks``."""
        return [self.read(t) for t in tasks]


def run_serial(job: Callable[[Any], Any], tasks: Sequence[Any], store: TaskStore,
               progress: Callable[[], object] | None = None) -> int:
    """Run the pending ``tasks`` one after the other in this process, storing each result; returns how many
    were computed. ``progress()`` is called after each."""
    todo = store.pending(tasks)
    for task in todo:
        store.write(task, job(task))
        if progress is not None:
            progress()
    return len(todo)
