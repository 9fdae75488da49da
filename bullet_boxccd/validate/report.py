"""The report file: JSON lines a run appends to, and resumes from.

The first line is the run's header (what determines every record: the command, seed,
shard size, families, tolerances). Every further line is one finished unit of work (a
shard of queries, a sweep task) keyed by ``key``; it is written and flushed to disk
as soon as the unit is done, so an interrupted run loses at most the units in flight.
Resuming reads the records back, keeps one per key (the last whole one: a line cut
short by the interruption is ignored) and runs only the units without a record, so
no unit is redone and none is counted twice. A report whose header differs from the
run's is refused rather than mixed.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

__all__ = ["ReportMismatchError", "Report"]


class ReportMismatchError(ValueError):
    """The report file belongs to a run with other parameters."""


class Report:
    """Records of one run, on disk at ``path`` (None: kept in memory only)."""

    def __init__(self, path, header: dict):
        self.path = None if path is None else Path(path)
        self.header = json.loads(json.dumps(header))  # as it reads back
        self.records: dict[str, dict] = {}
        if self.path is not None and self.path.exists() and self.path.stat().st_size:
            self._load()
        elif self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._append(self.header)

    def _load(self):
        text = self.path.read_text()
        if not text.endswith("\n"):
            self.path.open("a").write("\n")  # end a line cut short, so the next record starts clean
        lines = text.splitlines()
        try:
            found = json.loads(lines[0])
        except json.JSONDecodeError:
            found = None
        if found != self.header:
            raise ReportMismatchError(f"{self.path} holds another run (header {lines[0][:200]}); expected "
                                      f"{json.dumps(self.header)[:200]}: pass another --report, or delete it")
        for line in lines[1:]:
            try:
                rec = json.loads(line)
            except json.JSONDecodeError:
                continue  # cut short by an interruption: that unit runs again
            if "key" in rec:
                self.records[rec["key"]] = rec

    def _append(self, obj):
        with open(self.path, "a") as fh:
            fh.write(json.dumps(obj, separators=(",", ":")) + "\n")
            fh.flush()
            os.fsync(fh.fileno())

    def add(self, record: dict):
        """Keep ``record`` (it has a ``key``) and append it to the file."""
        self.records[record["key"]] = record
        if self.path is not None:
            self._append(record)

    def note(self, obj: dict):
        """Append a line that is not a record (a summary for readers; ignored on resume)."""
        if self.path is not None:
            self._append(obj)
