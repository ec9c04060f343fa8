"""``cmlt flicker --cvvdp``: ColorVideoVDP's JOD beside TF/GF when the optional cvvdp
package runs here, else the reason it does not, in the table and the JSON; it needs a
reference (a full-reference metric)."""
import json

import numpy as np
import pytest

from cmlt.cli import main
from cmlt.io.exr import write_exr
from cmlt.metrics import cvvdp


def _seq(d, frames):
    d.mkdir(parents=True, exist_ok=True)
    for i, im in enumerate(frames, 1):
        write_exr(str(d / f"s.{i:04d}.exr"), im.astype(np.float32))
    return str(d / "s.####.exr")


@pytest.fixture
def clip(tmp_path):
    rng = np.random.default_rng(3)
    ref = np.clip(rng.uniform(0.1, 0.6, (24, 24, 3)), 0, None)
    noisy = [ref * (1 + 0.3 * rng.standard_normal(ref.shape)) for _ in range(4)]
    return (tmp_path, _seq(tmp_path / "r", [ref] * 4), _seq(tmp_path / "n", noisy),
            _seq(tmp_path / "c", [ref] * 4))


def test_cvvdp_needs_a_reference(clip, capsys):
    tmp, refs, noisy, _ = clip
    assert main(["flicker", noisy, "--cvvdp"]) == 2
    assert "--cvvdp needs --reference" in capsys.readouterr().err


def test_cvvdp_reports_jod_or_why_not(clip, capsys):
    tmp, refs, noisy, same = clip
    out = tmp / "f.json"
    assert main(["flicker", noisy, "--reference", refs, "--cvvdp", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    data = json.loads(out.read_text())
    assert data["tf"] is not None                      # TF/GF are reported either way
    why = cvvdp.unavailable()
    if why:
        assert data["cvvdp"]["jod"] is None
        assert data["cvvdp"]["unavailable"] == why and "cvvdp" in why
        assert "ColorVideoVDP: not run" in text
        with pytest.raises(cvvdp.CvvdpUnavailable):
            cvvdp.video_jod(np.zeros((2, 4, 4, 3)), np.zeros((2, 4, 4, 3)))
    else:
        jod = data["cvvdp"]["jod"]
        assert 0 <= jod < 9.5 and "JOD" in text
        assert main(["flicker", same, "--reference", refs, "--cvvdp", "--json", str(out)]) == 0
        assert json.loads(out.read_text())["cvvdp"]["jod"] > max(9.5, jod)
