"""`verify` / `export` on hand-broken manifests and hash files: a clear error or a corrupt report, no traceback."""
from __future__ import annotations

import json

import pytest

from scenes.errors import UserInputError
from simulator.dataset.generate import DATASET_FORMAT, dataset_sequences, verify_dataset
from simulator.files import write_hashes


def _dataset(tmp_path, manifest_update=None):
    seq = tmp_path / "sequences" / "seq000001"
    seq.mkdir(parents=True)
    (seq / "meta.json").write_text("{}\n")
    content = write_hashes(seq)
    manifest = {"format": DATASET_FORMAT, "complete": True,
                "sequences": [{"name": "seq000001", "index": 0, "split": "train", "content_sha256": content}]}
    manifest.update(manifest_update or {})
    (tmp_path / "manifest.json").write_text(json.dumps(manifest))
    return tmp_path, seq


def test_intact_dataset_verifies(tmp_path):
    root, _ = _dataset(tmp_path)
    assert verify_dataset(root).ok


@pytest.mark.parametrize("garbage", ["not a hash line", "abc  meta.json", "z" * 64 + "  meta.json", "0" * 64 + "  "])
def test_garbage_line_in_hash_file_is_reported_corrupt(tmp_path, garbage):
    root, seq = _dataset(tmp_path)
    (seq / "files.sha256").write_text((seq / "files.sha256").read_text() + garbage + "\n")
    report = verify_dataset(root)
    assert not report.ok and report.corrupt == {"seq000001": ["files.sha256 (line 2 is not '<sha256>  <path>')"]}


def test_binary_hash_file_is_reported_corrupt(tmp_path):
    root, seq = _dataset(tmp_path)
    (seq / "files.sha256").write_bytes(b"\xff\xfe\x00garbage")
    assert verify_dataset(root).corrupt == {"seq000001": ["files.sha256"]}


@pytest.mark.parametrize("update,message", [
    ({"sequences": None}, "key 'sequences' is missing or not a list"),
    ({"sequences": {"a": 1}}, "key 'sequences' is missing or not a list"),
    ({"sequences": ["seq000001"]}, r"sequences\[0\].name must be a plain folder name"),
    ({"sequences": [{"name": "../../etc"}]}, r"sequences\[0\].name must be a plain folder name"),
    ({"sequences": [{"name": "seq000001", "split": "/abs/dir"}]}, r"sequences\[0\].split must be a plain folder name"),
])
def test_malformed_manifest_entries_are_refused(tmp_path, update, message):
    root, _ = _dataset(tmp_path, update)
    with pytest.raises(UserInputError, match=message):
        verify_dataset(root)
    with pytest.raises(UserInputError, match=message):
        dataset_sequences(root)


def test_manifest_that_is_not_an_object(tmp_path):
    root, _ = _dataset(tmp_path)
    (root / "manifest.json").write_text("[1, 2]")
    with pytest.raises(UserInputError, match="expected a JSON object"):
        verify_dataset(root)


def test_missing_sequences_key_entirely(tmp_path):
    root, _ = _dataset(tmp_path)
    manifest = json.loads((root / "manifest.json").read_text())
    del manifest["sequences"]
    (root / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(UserInputError, match="'sequences'"):
        verify_dataset(root)
