"""The dataset driver with a toy kind: the journal is bounded, records what finished, and resumes."""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from simulator.dataset import driver
from simulator.dataset.driver import GenerationFailed, Unit, drive


@dataclass
class ToyKind:
    """Units are text files units/<name>.txt; ``fail`` names units whose writer raises."""

    n: int
    fail: set = field(default_factory=set)
    written: list = field(default_factory=list)
    noun: str = "unit"

    @property
    def label(self) -> str:
        return "toy"

    def identity(self) -> str:
        return hashlib.sha256(f"toy{self.n}".encode()).hexdigest()

    def units(self) -> list[Unit]:
        return [Unit(f"u{k:03d}", k) for k in range(self.n)]

    def prepare(self, out: Path) -> None:
        (out / "units").mkdir(exist_ok=True)

    def unit_hash(self, out: Path, unit: Unit) -> str:
        return hashlib.sha256((out / "units" / f"{unit.name}.txt").read_bytes()).hexdigest()

    def unit_ok(self, out: Path, unit: Unit, recorded_hash: str | None) -> bool:
        path = out / "units" / f"{unit.name}.txt"
        return recorded_hash is not None and path.is_file() and self.unit_hash(out, unit) == recorded_hash

    def run(self, out: Path, todo: list[Unit], *, workers: int, progress: bool):
        for u in todo:
            if u.name in self.fail:
                yield {"name": u.name, "error": "RuntimeError: boom"}
                continue
            (out / "units" / f"{u.name}.txt").write_text(str(u.payload))
            self.written.append(u.name)
            yield {"name": u.name}

    def manifest(self, units, hashes, complete, out):  # a format is_evids_output knows, so a rerun may resume
        return {"format": "trident", "dataset_id": self.identity(), "complete": complete,
                "clips": [{"name": u.name, "content_sha256": hashes.get(u.name)} for u in units]}


def test_the_journal_is_not_rewritten_per_unit(tmp_path, monkeypatch):
    writes = []
    real = driver.write_manifest
    monkeypatch.setattr(driver, "write_manifest", lambda out, m: (writes.append(m["complete"]), real(out, m)))
    drive(ToyKind(200), tmp_path / "d", progress=False)
    assert writes[-1] is True and len(writes) <= 5        # first, maybe one timed, the stop, the final
    manifest = json.loads((tmp_path / "d" / "manifest.json").read_text())
    assert manifest["complete"] and all(c["content_sha256"] for c in manifest["clips"])


def test_a_failed_run_records_what_finished_and_the_rerun_writes_only_the_rest(tmp_path, monkeypatch):
    monkeypatch.setattr(driver, "JOURNAL_INTERVAL_S", 1e9)   # only the stop writes the journal
    with pytest.raises(GenerationFailed, match="u003: RuntimeError: boom"):
        drive(ToyKind(6, fail={"u003"}), tmp_path / "d", progress=False)
    partial = json.loads((tmp_path / "d" / "manifest.json").read_text())
    assert partial["complete"] is False
    assert [c["content_sha256"] is not None for c in partial["clips"]] == [True, True, True, False, True, True]
    again = ToyKind(6)
    result = drive(again, tmp_path / "d", progress=False)
    assert again.written == ["u003"] and result.rendered == ["u003"] and len(result.skipped) == 5
