"""What the frame loop does around each frame's render (DESIGN.md §4).

Before the render (:meth:`TemporalDriver.prepare`):

* the seed: the shot seed for every frame (stored seeds: the core's streams
  are keyed by (seed, domain, chain, proposal, dimension), never by frame,
  so consecutive frames use the same numbers), or with ``seed_per_frame`` a
  per-frame seed mixed from (shot seed, frame) — for comparison;
* with ``carry_states`` and a previous frame (in memory, or its state file):
  the previous chain population is evaluated in this frame's scene, the
  refresh pool is evaluated, and the chain starts are the deterministic-
  mixture importance resampling of both (core ``temporal_*``,
  ``src/core/temporal/carry.h`` explains why the start is unbiased).

After it (:meth:`TemporalDriver.finish`): the normalisation record
(:mod:`.normalization`), the image rescaled to the b it should use, and the
encoded state of this frame — which the driver then parses back for the next
frame, so the in-memory path and a job that reads the file see the same
values bit for bit.
"""
from __future__ import annotations

import math
from typing import List, Optional, Tuple

import numpy as np

from .normalization import NormRecord, paired_difference, update_normalization
from .state import (FrameState, StateError, check_compatible, decode_state, encode_state,
                    read_state, settings_hash, shot_hash, state_path)

__all__ = ["TemporalDriver", "frame_seed", "STATE_INTEGRATORS", "CHAIN_SETTINGS"]

#: integrators whose chains export / import states (RenderResult.mlt_states)
STATE_INTEGRATORS = ("pssmlt", "cmlt")
#: settings that change the chains: a state written with others is refused
CHAIN_SETTINGS = ("integrator", "spp", "max_depth", "sigma", "large_step_probability", "chains",
                  "bootstrap_samples", "tries", "inner_length", "inner", "importance",
                  "direct_fraction", "pilot_spp", "carry_states", "smooth_normalization",
                  "seed_per_frame", "time_budget")
#: integrators with a normalisation b (and bootstrap values, a pilot image)
MLT_INTEGRATORS = ("pssmlt", "cmlt")
#: share of the carried population taken from the states the chains *started* the
#: previous frame from (replayed with the same numbers: where the scene did not change
#: the chain retraces the previous frame's trajectory); the rest from the states they
#: *ended* in (rejuvenated by the previous frame's mutations). See plan_refresh.
#: Measured (tests/bench/flicker.py, 48x48, 16 evaluations/px, 8 frames, pssmlt): the
#: static shot's TF 0.048 / 0.0066 / 0.0041 and GF 0.0006 / 0.0023 / 0.0003 at 0, 0.5,
#: 0.75 (independent frames: TF 0.125, GF 0.0078); moving_light TF 0.094 / 0.081 and
#: relMSE 0.046 / 0.049 at 0.5 / 0.75 (stored seeds alone: TF 0.119, relMSE 0.042).
REPLAY_FRACTION = 0.75
#: pool ids of gathered pool states start here (carried states keep theirs)
_POOL_ID_BASE = 1 << 32

_M64 = (1 << 64) - 1


def _splitmix64(x: int) -> int:
    x = (x + 0x9E3779B97F4A7C15) & _M64
    x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & _M64
    x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & _M64
    return x ^ (x >> 31)


def frame_seed(seed: int, frame: float, per_frame: bool) -> int:
    """The core seed of a frame: the shot seed (stored seeds), or with
    ``per_frame`` a 64-bit mix of (shot seed, frame in thousandths)."""
    if not per_frame:
        return int(seed)
    key = int(round(float(frame) * 1000.0)) & _M64
    return _splitmix64(_splitmix64(int(seed) & _M64) ^ key)


def plan_refresh(core, f_old, f_new, pool_f, b_prev: float, n: int, u0: float,
                 mix=None) -> dict:
    """Chain starts of frame f+1: ``n − r`` resampled from the carried states
    ∝ w_i = m_i f*_{f+1}(u_i)/f*_f(u_i) and ``r`` from the refresh pool ∝ f*_{f+1}
    (both systematic, one keyed uniform). ``mix`` (m_i, default 1): mixture
    weights of the carried groups — carried states may be the union of two
    populations that both target π_f (the previous frame's start and end
    states); weighting each group by its share α, 1 − α keeps the union a
    sample of π_f (a mixture of two π_f samples), so the reweighted,
    resampled starts target π_{f+1} as before.

    Carried particles ~ π_f reweighted by w are an importance sample of
    π_{f+1} restricted to the support of f*_f; the pool (uniform points
    reweighted by f*_{f+1}) is one of all of π_{f+1}. ``r`` is the share of
    π_{f+1} the carried population cannot see, estimated as
    ``1 − b_ratio/b_pool`` (b_ratio/b_f = mean w, b_pool = mean pool f*),
    used only where that deficit is significant (> 3 standard errors of the
    pool mean), plus one start per carried state that lost its contribution
    (w = 0). In a static scene r = 0 and every w = 1, so each chain continues
    from its own state — which is what makes stored seeds + carried states
    settle. (core.temporal_plan_carry is the deterministic-mixture variant:
    exact for any overlap, but it replaces low-f* carried states by pool
    points every frame, so chains never settle; measured worse flicker.)
    """
    r = core.temporal_ratio_statistics(f_old, f_new)
    pool = np.asarray(pool_f, dtype=np.float64)
    lost = int(r["zero"])
    missing = 0.0
    if pool.size > 1 and r["count"] > 0 and b_prev > 0:
        b_pool = float(pool.mean())
        se = float(pool.std(ddof=1)) / math.sqrt(pool.size)
        b_ratio = b_prev * float(r["mean"])
        if b_pool - b_ratio > 3.0 * se and b_pool > 0:
            missing = min(1.0, (b_pool - b_ratio) / b_pool)
    n_refresh = min(n, max(lost, int(round(missing * n))))
    mix = [1.0] * len(f_old) if mix is None else list(mix)
    carried_picks = core.temporal_systematic_resample(
        [m * b / a if a > 0 and b > 0 else 0.0 for a, b, m in zip(f_old, f_new, mix)],
        n - n_refresh, u0)
    if not carried_picks:
        n_refresh = n
    pool_picks = core.temporal_systematic_resample(list(pool_f), n_refresh, u0) \
        if n_refresh > 0 else []
    picks = list(carried_picks) + [len(f_old) + j for j in pool_picks]
    return {"picks": picks, "from_carried": len(carried_picks), "from_pool": len(pool_picks),
            "missing": missing}


def keep_chain_identity(picks: List[int], n_carried: int) -> List[int]:
    """Assign the resampled starts to chain slots so that chain k starts from
    its own carried particle k (with the union of start and end states, the
    state chain k started the previous frame from) whenever that particle was
    picked; the other picks fill the remaining slots in order.

    Only the assignment changes, not the set of starts: chain k's random
    numbers are independent of which start it gets, so the population is
    distributed as before. But with stored seeds chain k then replays the
    numbers it used in the previous frame from where it stopped; in a static
    scene its trajectory meets the previous one at the first large step both
    accept, and from there on the frames agree (the flicker dies out).
    """
    n = len(picks)
    slots: List[Optional[int]] = [None] * n
    rest: List[int] = []
    for p in picks:
        if p < n_carried and p < n and slots[p] is None:
            slots[p] = p
        else:
            rest.append(p)
    it = iter(rest)
    return [s if s is not None else next(it) for s in slots]


class TemporalDriver:
    """State carried from frame to frame of one job. ``settings``: the
    resolved :class:`cmlt.settings.RenderSettings`."""

    def __init__(self, core, settings, shot: str, width: int, height: int,
                 state_dir: Optional[str] = None, fresh_start_on_bad_state: bool = False,
                 warn=None):
        self.core = core
        self.settings = settings
        self.base_seed = int(settings.seed)
        self.per_frame = bool(settings.seed_per_frame)
        self.smooth = bool(settings.smooth_normalization)
        self.integrator = str(settings.integrator)
        self.carry = bool(settings.carry_states) and self.integrator in STATE_INTEGRATORS
        self.state_dir = state_dir
        self.fresh_on_bad = bool(fresh_start_on_bad_state)
        self.warn = warn or (lambda msg: None)
        self.shot_hash = shot_hash(shot)
        self.size = (int(width), int(height))
        d = settings.as_dict()
        self.settings_hash = settings_hash({k: d.get(k) for k in CHAIN_SETTINGS})
        self.prev: Optional[FrameState] = None
        self.prev_source: Optional[str] = None
        self._pending: dict = {}

    # ---- state in -------------------------------------------------------------
    def _check(self, s: FrameState, path: str, frame: float) -> None:
        check_compatible(s, path, shot_hash_=self.shot_hash, width=self.size[0],
                         height=self.size[1], integrator=self.integrator, seed=self.base_seed,
                         settings_hash_=self.settings_hash, frame=frame)

    def load_previous(self, prev_frame: float, first_frame: float) -> Optional[str]:
        """Before the first frame a job renders: read ``state.<prev_frame>.bin``
        from the state directory (if any). Returns a note for the log, or None.
        A bad state file raises :class:`StateError` unless
        ``fresh_start_on_bad_state`` (then a warning and a fresh start)."""
        self.prev = None
        if not self.state_dir:
            return None
        path = state_path(self.state_dir, prev_frame)
        import os
        if not os.path.exists(path):
            return None
        try:
            s = read_state(path)
            self._check(s, path, prev_frame)
        except StateError as exc:
            if not self.fresh_on_bad:
                raise
            self.warn(f"{exc}; starting frame {first_frame:g} fresh "
                      "(--fresh-start-on-bad-state)")
            return None
        self.prev = s
        self.prev_source = path
        return f"continuing from {path}"

    # ---- per frame ------------------------------------------------------------
    def prepare(self, scene, st, frame: float) -> dict:
        """Set the seed and the chain starts of ``st`` (core.RenderSettings)
        for ``frame``; returns the temporal record so far."""
        core = self.core
        st.seed = frame_seed(self.base_seed, frame, self.per_frame)
        if hasattr(st, "mlt_initial_states"):
            st.mlt_initial_states = None
        rec = {"seed": int(st.seed), "seed_per_frame": self.per_frame,
               "carry_states": self.carry, "smooth_normalization": self.smooth,
               "state_in": None, "carried_chains": 0, "refreshed_chains": 0}
        self._pending = {"ratio": None, "pool_f": []}
        if self.integrator in MLT_INTEGRATORS and hasattr(st, "pilot"):
            # the pixel importance's pilot, rendered once for the render and for the
            # carry-over evaluations below (f* must be the same function in all of them)
            st.pilot = None
            if str(getattr(st, "importance", "luminance")) == "pixel":
                st.pilot = core.render_pilot(scene, st)
        if not self.carry:
            return rec
        n_pool = int(self.settings.chains)
        pool = core.temporal_sample_pool(scene, st, self.base_seed, n_pool)
        pool_f = list(core.temporal_f_star(pool))
        self._pending["pool_f"] = pool_f
        prev = self.prev
        if prev is not None and prev.chain_states and prev.last is not None:
            end = core.MltStates.from_bytes(prev.chain_states)
            start = core.MltStates.from_bytes(prev.start_states) if prev.start_states else None
            alpha = REPLAY_FRACTION if start is not None and len(start) == len(end) else 0.0
            if alpha >= 1.0:
                carried, mix = start, [1.0] * len(start)
            elif alpha > 0.0:
                # slots 0..n-1: the start states (chain k's own first: keep_chain_identity)
                carried = core.temporal_concat_states(start, end)
                mix = [alpha] * len(start) + [1.0 - alpha] * len(end)
            else:
                carried, mix = end, [1.0] * len(end)
            ev = core.temporal_evaluate_states(scene, st, carried)
            f_old = list(core.temporal_f_star(carried))
            f_new = list(core.temporal_f_star(ev))
            u0 = core.temporal_carry_uniform(int(st.seed), 0)
            plan = plan_refresh(core, f_old, f_new, pool_f, float(prev.last.b_used),
                                int(self.settings.chains), u0, mix=mix)
            if plan["picks"]:
                picks = keep_chain_identity(list(plan["picks"]), min(len(f_old), len(end)))
                st.mlt_initial_states = core.temporal_gather_states(ev, pool, picks,
                                                                    _POOL_ID_BASE)
            self._pending["ratio"] = core.temporal_ratio_statistics(f_old, f_new)
            rec.update(state_in=self.prev_source, carried_chains=int(plan["from_carried"]),
                       refreshed_chains=int(plan["from_pool"]),
                       ratio_mean=float(self._pending["ratio"]["mean"]),
                       carried_lost=int(self._pending["ratio"]["zero"]),
                       replay_fraction=alpha)
        return rec

    def finish(self, result, stats: dict, image: np.ndarray, frame: float,
               rec: dict) -> Tuple[np.ndarray, dict, bytes]:
        """Normalisation of the frame just rendered; returns (image rescaled to
        the b it uses, temporal record, encoded state bytes). The driver then
        continues from those bytes (:meth:`advance`)."""
        prev = self.prev
        last = prev.last if prev is not None else None
        b = stats.get("b")
        history: List[NormRecord] = list(prev.history) if prev is not None else []
        boot = getattr(result, "bootstrap_f", None)
        boot = np.asarray(boot, dtype=np.float32) if boot is not None else None
        if b is None:                           # no normalisation (pt, bdpt)
            norm = None
        else:
            paired = None
            if prev is not None and prev.boot_f and boot is not None and not self.per_frame:
                paired = paired_difference(np.frombuffer(prev.boot_f, dtype="<f4"), boot)
            norm = update_normalization(frame, float(b), float(stats.get("b_stderr", 0.0)),
                                        prev=last, ratio=self._pending.get("ratio"),
                                        smooth=self.smooth, paired=paired)
            history.append(norm)
            if self.smooth and float(b) > 0 and norm.b_used != float(b):
                # only the chains' part scales with b (the direct pass is plain Monte Carlo)
                img = np.asarray(image, dtype=np.float64)
                direct = getattr(result, "direct", None)
                base = np.asarray(direct, dtype=np.float64) if direct is not None else 0.0
                image = (base + (img - base) * (norm.b_used / float(b))).astype(np.float32)
            rec.update(b_boot=norm.b_fresh, b_boot_stderr=norm.s_fresh,
                       b_bootstrap=stats.get("b_bootstrap"),
                       b_ratio=norm.b_ratio, b_ratio_stderr=norm.s_ratio,
                       b_combined=norm.b_combined, b_smoothed=norm.b_smoothed,
                       b_used=norm.b_used, change_detected=bool(norm.change),
                       b_delta=norm.delta, b_delta_stderr=norm.s_delta)
        states = getattr(result, "mlt_states", None)
        starts = getattr(result, "mlt_start_states", None)
        chain_bytes = bytes(states.to_bytes()) if (self.carry and states is not None) else b""
        start_bytes = bytes(starts.to_bytes()) if (self.carry and starts is not None) else b""
        fs = FrameState(shot_hash=self.shot_hash, width=self.size[0], height=self.size[1],
                        integrator=self.integrator, seed=self.base_seed, frame=float(frame),
                        settings_hash=self.settings_hash, chain_states=chain_bytes,
                        start_states=start_bytes,
                        chain_count=len(states) if (chain_bytes and states is not None) else 0,
                        pool_f=list(self._pending.get("pool_f", [])),
                        boot_f=boot.astype("<f4").tobytes() if boot is not None else b"",
                        history=history)
        data = encode_state(fs)
        return image, rec, data

    def advance(self, data: bytes, source: str) -> None:
        """Continue from this frame's encoded state (the same bytes a later job
        reads from the file)."""
        self.prev = decode_state(data, source)
        self.prev_source = source

    def forget(self) -> None:
        self.prev = None
        self.prev_source = None
