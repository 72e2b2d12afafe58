"""What a batch reports: ``OUT/report.jsonl`` (one record a row) and the summary table."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

from .manifest import ManifestRow

__all__ = ["REPORT_NAME", "BatchReport"]

#: The batch's record of every row, in ``OUT``.
REPORT_NAME = "report.jsonl"


@dataclass
class BatchReport:
    """What a batch did.

    Attributes
    ----------
    records : list of dict
        One per manifest row, in its order (see :func:`build_person`); rows finished by an
        earlier run have ``skipped`` True.
    out_dir : Path
    seconds : float
        Wall time of this run.
    """

    records: list[dict]
    out_dir: Path
    seconds: float

    def count(self, status: str) -> int:
        if status == "skipped":
            return sum(bool(r.get("skipped")) for r in self.records)
        if status == "built":
            return sum(r["status"] == "done" and not r.get("skipped") for r in self.records)
        return sum(r["status"] == status for r in self.records)

    @property
    def failed(self) -> list[dict]:
        return [r for r in self.records if r["status"] == "failed"]

    @property
    def heads_per_minute(self) -> float:
        return 60.0 * self.count("built") / self.seconds if self.seconds > 0 else 0.0

    def summary(self) -> str:
        """One line: how many were built, skipped and failed, in how long."""
        return (f"{self.count('built')} built, {self.count('skipped')} done before, {self.count('failed')} failed "
                f"in {self.seconds:.0f} s ({self.heads_per_minute:.1f} heads/min); report: "
                f"{self.out_dir / REPORT_NAME}")

    def table(self, max_rows: int = 40):
        """A :class:`rich.table.Table` of the rows (the failed and unreviewed ones first
        when there are more than ``max_rows``)."""
        from rich.table import Table

        table = Table(title=f"recon batch: {self.out_dir}", title_justify="left")
        for name, kw in (("id", {}), ("status", {}), ("s", {"justify": "right"}), ("note", {"overflow": "fold"})):
            table.add_column(name, **kw)
        rows = self.records
        if len(rows) > max_rows:
            rows = [r for r in rows if r["status"] == "failed" or r.get("unreviewed") or r.get("stale")][:max_rows]
        for r in rows:
            status = "done before" if r.get("skipped") else r["status"]
            style = "red" if r["status"] == "failed" else ("yellow" if r.get("unreviewed") else None)
            note = r.get("error") or "; ".join(
                [*(["points unreviewed (automatic detection)"] if r.get("unreviewed") else []),
                 *([r["stale"]] if r.get("stale") else []),
                 *(f"clone: {w}" for w in r.get("clone_warnings", [])[:2])])
            table.add_row(r["id"], status, f"{r.get('seconds', 0):.1f}", note, style=style)
        if len(rows) < len(self.records):
            table.caption = f"and {len(self.records) - len(rows)} more rows done (all in {REPORT_NAME})"
        return table


class _Report:
    """``OUT/report.jsonl``: a line appended (and flushed to disk) as each row ends, so an
    interrupted batch keeps what it learnt; rewritten in the manifest's order at the end."""

    def __init__(self, out: Path):
        self.path = out / REPORT_NAME
        self.latest = self._read()
        self.file = open(self.path, "a", encoding="utf-8")

    def _read(self) -> dict[str, dict]:
        latest = {}
        if self.path.exists():
            for text in self.path.read_text(encoding="utf-8").splitlines():
                try:
                    r = json.loads(text)
                    latest[r["id"]] = r
                except (ValueError, KeyError, TypeError):  # a line cut short by a kill
                    continue
        return latest

    def add(self, record: dict) -> None:
        self.latest[record["id"]] = record
        self.file.write(json.dumps(record) + "\n")
        self.file.flush()
        os.fsync(self.file.fileno())

    def close(self, rows: list[ManifestRow]) -> list[dict]:
        from mpeg4.io.atomic import atomic_write

        self.file.close()
        records = [self.latest[r.id] for r in rows if r.id in self.latest]
        with atomic_write(self.path, "w") as f:
            for r in records:
                f.write(json.dumps(r) + "\n")
        return records
