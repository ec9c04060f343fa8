"""Clean diagnostics for ``.mtlx`` references: usd-core cannot compose them
("Could not open asset ... Cannot determine file format"), but cmlt's MaterialX
reader reads the document, so that raw USD line is not a warning; a document that
cannot be read is one warning naming the material and the file; ``cmlt inspect``
notes the reference; a ``.mtlx`` sublayer, which the reader does not read, still
warns. The renders run in a child process so that stderr is the CLI's own."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from cmlt.io.exr import read_exr

from mtlx_test_stages import mtlx_document, stage_with_mtlx, surface_xml

RED_DOC = mtlx_document(surface_xml("open_pbr_surface",
                                    {"base_color": ("color3", "0.8, 0.05, 0.05")}))


def _cmlt(args, cwd):
    env = dict(os.environ)
    env.pop("OCIO", None)
    return subprocess.run([sys.executable, "-m", "cmlt", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


def _render_json(shot, out, cwd):
    proc = _cmlt(["render", shot, "--out", out, "--spp", "4", "--res", "16x16", "--threads",
                  "2", "--integrator", "pt", "--log-json"], cwd)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == "", proc.stderr                 # nothing raw on stderr
    events = [json.loads(line) for line in proc.stdout.splitlines()]
    return [e["message"] for e in events if e["event"] == "warning"]


def test01_a_readable_document_gives_no_usd_warning_and_renders(tmp_path):
    shot = stage_with_mtlx(tmp_path, RED_DOC, light=45.0)
    out = str(tmp_path / "r.exr")
    warnings = _render_json(shot, out, tmp_path)
    assert not any("Could not open asset" in w or "Cannot determine file format" in w
                   or "SDF_FORMAT_ARGS" in w for w in warnings), warnings
    img, _ = read_exr(out)
    m = np.asarray(img, np.float64)[4:12, 4:12, :3].mean((0, 1))
    assert m[0] > 3 * m[2], m                              # the document's red, not grey
    proc = _cmlt(["inspect", shot], tmp_path)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    assert "references the MaterialX document" in proc.stdout and "look.mtlx" in proc.stdout
    assert "Could not open asset" not in proc.stdout


def test02_a_missing_document_is_one_warning_naming_it(tmp_path):
    shot = stage_with_mtlx(tmp_path, RED_DOC)
    os.remove(tmp_path / "look.mtlx")
    warnings = _render_json(shot, str(tmp_path / "m.exr"), tmp_path)
    named = [w for w in warnings if "look.mtlx" in w]
    assert len(named) == 1, warnings
    assert "/Mtl/Materials/M" in named[0] and "cannot read the MaterialX document" in named[0]


def test03_a_mtlx_sublayer_still_warns(tmp_path):
    shot = stage_with_mtlx(tmp_path, RED_DOC)
    text = open(shot).read().replace("(\n", '(\n    subLayers = [@./look.mtlx@]\n', 1)
    with open(shot, "w") as f:
        f.write(text)
    warnings = _render_json(shot, str(tmp_path / "s.exr"), tmp_path)
    assert any("look.mtlx" in w and "sublayer" in w.lower() for w in warnings), warnings
