"""The package version read from the dist-info's METADATA (cmlt._version) is what
importlib.metadata reads; a tree without a dist-info falls back to it."""
import importlib.metadata
import sys

import cmlt._version as v


def test_01_version_is_the_installed_distributions():
    assert v.__version__ == importlib.metadata.version("cmlt")
    assert v._from_dist_info() == importlib.metadata.version("cmlt")


def test_02_first_dist_info_on_the_path_wins(tmp_path, monkeypatch):
    for i, ver in enumerate(("9.8.7", "1.2.3")):
        d = tmp_path / f"p{i}" / f"cmlt-{ver}.dist-info"
        d.mkdir(parents=True)
        (d / "METADATA").write_text(f"Metadata-Version: 2.1\nName: cmlt\nVersion: {ver}\n\nVersion: 0.0.0\n")
    (tmp_path / "not_a_dir.zip").write_bytes(b"PK")
    monkeypatch.setattr(sys, "path", [str(tmp_path / "not_a_dir.zip"), str(tmp_path / "missing"),
                                      str(tmp_path / "p0"), str(tmp_path / "p1")])
    assert v._from_dist_info() == "9.8.7"


def test_03_no_dist_info_found(tmp_path, monkeypatch):
    monkeypatch.setattr(sys, "path", [str(tmp_path)])
    assert v._from_dist_info() is None
