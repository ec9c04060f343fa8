"""The builds of the core for newer x86-64 levels (cmlt/_core_select.py): which one a
process loads, the errors CMLT_CORE_ISA gives, and that every build renders the same
images bit for bit and says which it is in the sidecar."""
from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import cmlt
import cmlt._core as core
from cmlt import _core_select as cs

import support

V4 = set(cs.VARIANTS["x86-64-v4"])
V3 = set(cs.VARIANTS["x86-64-v3"])


def test_01_auto_takes_the_best_build_the_cpu_runs():
    both = ["x86-64-v4", "x86-64-v3"]
    assert cs.choose(both, None, V4) == "x86-64-v4"
    assert cs.choose(both, "", V3) == "x86-64-v3"          # no AVX-512: the AVX2 build
    assert cs.choose(both, "auto", V3 - {"fma"}) == cs.BASELINE
    assert cs.choose(["x86-64-v3"], "AUTO", V4) == "x86-64-v3"  # v4 not built
    assert cs.choose([], None, V4) == cs.BASELINE
    assert cs.choose(both, None, set()) == cs.BASELINE      # unknown CPU
    assert cs.choose(both, "baseline", V4) == cs.BASELINE
    assert cs.choose(both, "x86-64", V4) == cs.BASELINE
    assert cs.choose(both, "x86-64-v4", V4) == "x86-64-v4"


def test_02_a_build_that_cannot_run_is_a_clear_error():
    with pytest.raises(cs.CoreSelectError, match=r"CMLT_CORE_ISA=x86-64-v4: this CPU .*avx512bw"):
        cs.choose(["x86-64-v4"], "x86-64-v4", V4 - {"avx512bw"})
    with pytest.raises(cs.CoreSelectError, match=r"CMLT_CORE_ISA=x86-64-v3: .*no core module built for x86-64-v3"):
        cs.choose(["x86-64-v4"], "x86-64-v3", V4)
    with pytest.raises(cs.CoreSelectError, match=r"CMLT_CORE_ISA='avx9'.*auto, baseline"):
        cs.choose(["x86-64-v4"], "avx9", V4)
    assert issubclass(cs.CoreSelectError, ImportError)


def test_03_cpu_flags_from_cpuinfo(tmp_path):
    if not cs.cpu_flags():
        pytest.skip("not Linux on x86-64: the portable build is loaded")
    info = tmp_path / "cpuinfo"
    info.write_text("processor\t: 0\nflags\t\t: fpu sse2 avx2 avx512f\nbugs\t\t: none\n")
    assert cs.cpu_flags(str(info)) == {"fpu", "sse2", "avx2", "avx512f"}
    assert cs.cpu_flags(str(tmp_path / "missing")) == frozenset()


def _available():
    here = Path(core.__file__)  # a variant lives in <the portable module's folder>/<level>/
    portable = here if core.isa == "x86-64" else here.parent.parent / here.name
    return cs.variants_beside(str(portable))


def test_04_the_loaded_build_is_the_chosen_one():
    request = os.environ.get(cs.ENV)
    want = cs.choose(_available(), request, cs.cpu_flags())
    assert core.isa == ("x86-64" if want == cs.BASELINE else want)
    assert Path(core.__file__).parent.name == (core.isa if core.isa != "x86-64" else "cmlt")


_RENDER = textwrap.dedent("""
    import hashlib, json, sys
    import numpy as np
    import OpenImageIO as oiio
    from cmlt.cli import main
    out, cases = sys.argv[1], json.loads(sys.argv[2])
    hashes = []
    for k, args in enumerate(cases):
        pattern = f"{out}/c{k}.####.exr"
        assert main(["render"] + args + ["--out", pattern, "--quiet"]) == 0
        for frame in (1, 2):
            path = pattern.replace("####", f"{frame:04d}")
            px = oiio.ImageBuf(path).get_pixels(oiio.FLOAT)
            side = json.load(open(path + ".json"))
            hashes.append([hashlib.sha256(np.ascontiguousarray(px).tobytes()).hexdigest(),
                           side["core_isa"], side["stats"]["samples"]])
    print(json.dumps(hashes))
""")


def _render(tmp: Path, isa: str, cases) -> list:
    tmp.mkdir()
    env = dict(os.environ, **{cs.ENV: isa})
    proc = subprocess.run([sys.executable, "-c", _RENDER, str(tmp), json.dumps(cases)], env=env,
                          capture_output=True, text=True, timeout=600, cwd=str(support.ROOT))
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_05_every_build_renders_the_same_images(tmp_path):
    flags = cs.cpu_flags()
    builds = [isa for isa in _available() if cs.supports(isa, flags)]
    if not builds:
        pytest.skip(f"no variant build this CPU runs (built: {_available() or 'none'})")
    seq = support.SEQUENCES
    common = ["--res", "40x30", "--frames", "1:2", "--threads", "2"]
    cases = [[str(seq / "cornell/shot.usda"), "--integrator", "pt", "--spp", "8"] + common,
             [str(seq / "textured_dome/shot.usda"), "--integrator", "pt", "--spp", "8"] + common,
             [str(seq / "caustic_glass/shot.usda"), "--integrator", "bdpt", "--spp", "4"] + common,
             [str(seq / "caustic_glass/shot.usda"), "--integrator", "cmlt", "--spp", "16",
              "--chains", "32", "--bootstrap-samples", "1000"] + common,
             [str(seq / "door_ajar/shot.usda"), "--integrator", "pssmlt", "--spp", "16",
              "--mlt-paths", "all", "--chains", "32", "--bootstrap-samples", "1000"] + common]
    ref = _render(tmp_path / "baseline", "baseline", cases)
    assert all(h[1] == "x86-64" for h in ref)
    for isa in builds:
        got = _render(tmp_path / isa, isa, cases)
        assert all(h[1] == isa for h in got)
        diff = [i for i, (a, b) in enumerate(zip(ref, got)) if a[0] != b[0] or a[2] != b[2]]
        assert not diff, f"{isa} differs from the portable build in renders {diff}"


def test_06_the_command_line_names_the_variable():
    env = dict(os.environ, **{cs.ENV: "avx9"})
    proc = subprocess.run([sys.executable, "-m", "cmlt", "--version"], env=env, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        "cmlt: error: CMLT_CORE_ISA='avx9': expected auto, baseline or one of x86-64-v4, x86-64-v3"]
    proc = subprocess.run([sys.executable, "-m", "cmlt", "--version"], env=dict(env, **{cs.ENV: "baseline"}),
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and proc.stdout.strip() == f"cmlt {cmlt.__version__} (core x86-64)"
