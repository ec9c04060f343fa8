"""``--integrator auto``: one integrator for a shot, from the effects of a few of its frames.

The rule (thresholds checked against equal-time benchmarks of every sequence,
``tests/bench/results/integrator_auto.md``):

1. **caustics that matter** — in some analysed frame the near-specular chains carry at
   least CAUSTIC_SHARE of the flux onto camera-visible diffuse surfaces: ``bdpt``
   (a path tracer finds L S+ D E paths only by hitting the light through the chain;
   BDPT's light tracing, t = 1, samples them from the light);
2. **hard visibility** — in some analysed frame fewer than HARD_DIRECT of the light
   samples at the camera's first diffuse hits reach a light *and* fewer than HARD_BOUNCE
   one diffuse bounce further: light reaches what the camera sees only through narrow
   openings (a door ajar), ``bdpt`` (its light subpaths start on the far side of the
   opening);
3. **indirect hot spots** — in some analysed frame the path tracer's first indirect
   bounce adds a relative variance of at least INDIRECT_NOISE to a camera sample
   (FrameEffects.indirect: share² × relative variance of the probes' one-bounce
   estimate): much of what the camera sees is lit by small bright patches, such as a
   ceiling half a metre above a small light, which cosine-sampled bounces rarely hit and
   BDPT's light subpaths start from (camera_pan 6.1, hard/tiny_sphere_light 2.6;
   cornell 0.31-0.38 over its 24 frames; every other sequence and hard stage below
   0.15, bulb_room 0.52);
4. otherwise ``pt``.

Why BDPT and not coherent MLT for 1 and 2: at equal time (96x96, 4 s, 2 threads, 3
seeds) BDPT had the lowest error on caustic_glass (cmlt 1.27x, pssmlt 1.21x its
relMSE) and on door_ajar's slit frame (cmlt 2.6x), and was within 1.15x of pt on
door_ajar's half-open frame, where cmlt was 7.5x; pt was best on every other sequence.
The fixed costs of the Metropolis integrators (100k bootstrap samples, pilot image)
weigh on frames this small; the rule follows the measurements, and
``--integrator cmlt`` stays one flag away.

Rule 3 (2026-12-05, ``tests/bench/results/integrator_auto.md``): on camera_pan bdpt had
3.2x less error than pt at equal time and on tiny_sphere_light 5.7x, while pt won on
cornell (1.75x), point_light (2.0x) and scale_unit (4.3x); the threshold 1.0 lies between
cornell (at most 0.38) and tiny_sphere_light (2.6), about 2.6x from each, chosen from
those three; point_light and scale_unit (0.15 each; pt better there) agree, but their
numbers were known when it was set. Held out afterwards: the Cornell box lit by a 3 cm
sphere light 30 cm under the ceiling (2.9, bdpt 6.5x better: right) and in the middle of
the box (0.40, pt chosen, bdpt 3.7x better: wrong) — the rule sees hot spots, not every
reason a small light favours bdpt.

One choice per shot, never per frame: chain states and the normalisation carry from
frame to frame only within one integrator. The analysed frames are the stage's first,
middle and last time codes (:func:`sample_frames`), so every job of a farm render of the
shot picks the same integrator; a stage without an authored time range uses the first,
middle and last frame asked for.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import List, Optional, Sequence

__all__ = ["AutoChoice", "choose_integrator", "sample_frames", "CAUSTIC_SHARE", "HARD_DIRECT",
           "HARD_BOUNCE", "INDIRECT_NOISE"]

#: caustics matter from this share of the camera-visible diffuse flux
CAUSTIC_SHARE = 0.01
#: hard visibility: below this fraction of light samples at the first hits reaching a light
HARD_DIRECT = 0.1
#: ... and below this fraction one diffuse bounce further
HARD_BOUNCE = 0.1
#: indirect hot spots: from this relative variance of pt's first indirect bounce
INDIRECT_NOISE = 1.0


@dataclass
class AutoChoice:
    name: str                       # pt | bdpt
    reason: str
    frames: List[float] = field(default_factory=list)    # the frames analysed
    #: the rule that decided: caustics, hard_visibility, hot_spots, or "" (pt: none did)
    rule: str = ""

    def as_dict(self) -> dict:
        return {"name": self.name, "reason": self.reason, "frames": list(self.frames),
                "rule": self.rule}


def sample_frames(frames: Sequence[float], start: Optional[float] = None,
                  end: Optional[float] = None) -> List[float]:
    """The frames ``auto`` analyses: first, middle and last of the stage's range
    [start, end] when given (the middle rounded down to a whole frame when both ends
    are whole), else of ``frames``; without duplicates, in order."""
    if start is not None and end is not None and end >= start:
        mid = 0.5 * (start + end)
        if float(start).is_integer() and float(end).is_integer():
            mid = float(int(mid))
        picks = [float(start), mid, float(end)]
    else:
        fl = [float(f) for f in frames]
        if not fl:
            return []
        picks = [fl[0], fl[len(fl) // 2], fl[-1]]
    out: List[float] = []
    for f in picks:
        if f not in out:
            out.append(f)
    return out


def choose_integrator(effects: Sequence) -> AutoChoice:
    """The rule of the module docstring over FrameEffects of the analysed frames."""
    frames = [fe.time for fe in effects]
    if not effects:
        return AutoChoice("pt", "no frame analysed", frames)
    best = max(effects, key=lambda fe: fe.caustic_share)
    if best.caustic_share >= CAUSTIC_SHARE:
        return AutoChoice("bdpt", (
            f"caustics: at frame {best.time:g}, {best.caustic_share * 100:.3g}% of the flux "
            f"onto camera-visible diffuse surfaces comes through specular chains "
            f"(>= {CAUSTIC_SHARE * 100:g}%)"), frames, "caustics")
    probed = [fe for fe in effects if fe.probes is not None and
              fe.visibility()["camera_diffuse_hits"] > 0]
    hard = [fe for fe in probed
            if fe.visibility()["direct_visible"] < HARD_DIRECT and
            fe.visibility()["bounce_visible"] < HARD_BOUNCE]
    if hard:
        fe = min(hard, key=lambda e: e.visibility()["direct_visible"])
        v = fe.visibility()
        return AutoChoice("bdpt", (
            f"hard visibility: at frame {fe.time:g} only {v['direct_visible'] * 100:.3g}% "
            f"of light samples at the camera's first diffuse hits reach a light and "
            f"{v['bounce_visible'] * 100:.3g}% one bounce further (< {HARD_DIRECT * 100:g}% "
            f"and < {HARD_BOUNCE * 100:g}%)"), frames, "hard_visibility")
    if not probed:
        return AutoChoice("pt", "no caustics found and no camera hits to probe visibility",
                          frames)
    noisy = max(probed, key=lambda e: e.indirect()["noise"])
    ind = noisy.indirect()
    if ind["noise"] >= INDIRECT_NOISE:
        return AutoChoice("bdpt", (
            f"indirect hot spots: at frame {noisy.time:g}, {ind['share'] * 100:.3g}% of the "
            f"light at the camera's first hits is one bounce indirect and its cosine-sampled "
            f"estimate has relative variance {ind['rel_var']:.3g} (share² × that = "
            f"{ind['noise']:.2g} >= {INDIRECT_NOISE:g})"), frames, "hot_spots")
    easiest = min(probed, key=lambda e: e.visibility()["direct_visible"])
    v = easiest.visibility()
    caus = (f"caustics carry at most {best.caustic_share * 100:.3g}% of the visible diffuse "
            f"flux" if any(fe["caustics"] for fe in effects) else "no caustic paths")
    return AutoChoice("pt", (
        f"{caus} (< {CAUSTIC_SHARE * 100:g}%); light is easy to reach (at least "
        f"{v['direct_visible'] * 100:.3g}% of light samples at the camera's first hits "
        f"reach it, frame {easiest.time:g}) and its indirect part smooth (share² × relative "
        f"variance at most {ind['noise']:.2g} < {INDIRECT_NOISE:g})"), frames)
