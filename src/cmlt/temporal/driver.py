"""What the frame loop does around each frame's render (DESIGN.md §4).

Before the render (:meth:`TemporalDriver.prepare`):

* the seed: the shot seed for every frame (stored seeds: the core's streams
  are keyed by (seed, domain, chain, proposal, dimension), never by frame,
  so consecutive frames use the same numbers), or with ``seed_per_frame`` a
  per-frame seed mixed from (shot seed, frame) — for comparison;
* with stored seeds, the screen motion (camera rays through the pixel centres,
  their hits followed into this frame): each pixel's sample key moves with its
  own pixel's motion (:func:`key_map`, a permutation: RenderSettings.pixel_keys)
  and the chains' film position with the median motion (the film offset);
* with ``carry_states``: the frame's bootstrap points are evaluated here
  (``temporal_bootstrap_states``; the render is given their f* and does not
  evaluate them again) and the chain starts are chosen among them — the first
  frame by systematic resampling ∝ f*, every later one *coupled* to the
  previous frame's starts (core ``temporal_couple_starts``): chain k keeps its
  start with probability min(1, q/p) (p, q: the start's resampling
  probability in the previous and in this frame) and is otherwise refreshed
  from the residual ∝ (q − p)^+. The starts are then distributed exactly as a
  fresh frame's (``src/core/temporal/carry.h``), so the expected image is
  unchanged; where the target did not change (q = p) every chain keeps its
  start and, with the same numbers, retraces the previous frame's path.

After it (:meth:`TemporalDriver.finish`): the normalisation record
(:mod:`.normalization`), the image rescaled to the b it should use, and the
encoded state of this frame — which the driver then parses back for the next
frame, so the in-memory path and a job that reads the file see the same
values bit for bit.
"""
from __future__ import annotations

import time
from typing import List, Optional, Tuple

import numpy as np

from .normalization import NormRecord, paired_difference, update_normalization
from .state import (FrameState, StateError, check_compatible, decode_state, encode_state,
                    read_state, settings_hash, shot_hash, state_path)

__all__ = ["TemporalDriver", "prepare_frame", "carry_of", "frame_seed", "STATE_INTEGRATORS", "CHAIN_SETTINGS"]

#: integrators whose chains export / import states (RenderResult.mlt_states)
STATE_INTEGRATORS = ("pssmlt", "cmlt")
#: settings that change the chains: a state written with others is refused
CHAIN_SETTINGS = ("integrator", "spp", "max_depth", "sigma", "large_step_probability", "chains",
                  "bootstrap_samples", "tries", "inner_length", "inner", "importance",
                  "direct_fraction", "pilot_spp", "carry_states", "smooth_normalization",
                  "seed_per_frame", "time_budget", "error_groups", "target_error",
                  "pixel_filter", "filter_radius", "mlt_camera_technique", "mlt_paths",
                  "emission_guiding", "sampler", "chainless_integrator", "mlt_sds",
                  "mlt_traced_caustics", "mlt_min_starts")
#: integrators with a normalisation b (and bootstrap values, a pilot image)
MLT_INTEGRATORS = ("pssmlt", "cmlt")
#: Measurements behind the carry-over: tests/bench/results/flicker_baseline.md (the
#: former carried population) and tests/bench/results/flicker.md.

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


def frame_key(frame: float) -> int:
    """32-bit key of a frame (thousandths of a frame) for the keyed uniforms of the
    chain-start coupling: a fresh keep test per chain and frame."""
    return int(round(float(frame) * 1000.0)) & 0xFFFFFFFF


#: follow the image's screen motion with the film offset (the pixels' sample keys
#: and the chains' film position; the flicker benchmark turns it off to measure what
#: it does)
REPROJECT = True
#: screen-motion anchors per frame (a grid of camera rays: what they hit, followed
#: into the next frame to measure how far the image moved): one per pixel up to this
#: many per axis (anchor_grid)
ANCHOR_MAX = 128
#: the pixels' sample keys follow each pixel's own screen motion (a key map: parallax,
#: moving objects); False: every key follows the film offset (one motion for the image)
PIXEL_KEYS = True


def anchor_grid(width: int, height: int) -> Tuple[int, int]:
    """The screen anchors' grid for a width x height frame: one per pixel, at most
    ANCHOR_MAX per axis (then the key map interpolates the motion between them)."""
    return max(1, min(int(width), ANCHOR_MAX)), max(1, min(int(height), ANCHOR_MAX))


def key_map(prev_keys, anchors, projected, width: int, height: int) -> Optional[np.ndarray]:
    """The pixels' sample keys of the next frame (uint32, H*W row-major, a permutation of
    0..H*W-1), following each pixel's own screen motion: pixel q's key (``prev_keys``,
    None: the identity) moves to the pixel its surface is in next frame, q + d(q) with
    d the anchors' displacement (``anchors`` on an :func:`anchor_grid`, ``projected``
    into the next frame; invalid ones — nothing hit, behind the camera — take the
    median) interpolated bilinearly at the pixel centre; a key pushed out of the image
    wraps around to the opposite edge. Where several keys land on one pixel the one
    nearest its centre stays (ties: the lower source index; wrapped keys after those
    that came from inside); the keys left over go to the pixels nobody reached, both in
    raster order. Under a pure whole-pixel pan that is the film offset's torus shift
    exactly. None when fewer than a quarter of the anchors are
    valid (no motion to follow). The map depends only on the geometry and the camera,
    never on a pixel's random numbers, so every pixel's estimator is unchanged."""
    W, H = int(width), int(height)
    n_x, n_y = anchor_grid(W, H)
    motion = _anchor_motion(anchors, projected)
    if motion is None or motion[0].shape[0] != n_x * n_y:
        return None
    d, ok = motion
    d[~ok] = np.median(d[ok], axis=0)
    d = d.reshape(n_y, n_x, 2)
    # bilinear interpolation of the grid's displacement at the pixel centres
    gx = np.clip((np.arange(W) + 0.5) * n_x / W - 0.5, 0.0, n_x - 1)
    gy = np.clip((np.arange(H) + 0.5) * n_y / H - 0.5, 0.0, n_y - 1)
    x0 = np.floor(gx).astype(np.int64)
    y0 = np.floor(gy).astype(np.int64)
    x1, y1 = np.minimum(x0 + 1, n_x - 1), np.minimum(y0 + 1, n_y - 1)
    fx, fy = (gx - x0)[None, :, None], (gy - y0)[:, None, None]
    D = ((d[y0][:, x0] * (1 - fx) + d[y0][:, x1] * fx) * (1 - fy)
         + (d[y1][:, x0] * (1 - fx) + d[y1][:, x1] * fx) * fy)
    tx = np.arange(W)[None, :] + 0.5 + D[..., 0]
    ty = np.arange(H)[:, None] + 0.5 + D[..., 1]
    ix, iy = np.floor(tx), np.floor(ty)
    inside = ((ix >= 0) & (ix < W) & (iy >= 0) & (iy < H)).ravel()
    # a key pushed out of the image wraps around to the opposite edge (the film
    # offset's torus), behind any key that reached that pixel from inside
    resid = (np.abs(tx - ix - 0.5) + np.abs(ty - iy - 0.5)).ravel() + np.where(inside, 0.0, 4.0)
    ok_t = np.isfinite(tx).ravel() & np.isfinite(ty).ravel()
    ixw = np.mod(np.where(ok_t, ix.ravel(), 0), W)
    iyw = np.mod(np.where(ok_t, iy.ravel(), 0), H)
    target = (iyw * W + ixw).astype(np.int64)
    src = np.flatnonzero(ok_t)
    # by target pixel, then distance from its centre (resid < 8), then source index
    order = src[np.argsort(target[src] + resid[src] / 8.0, kind="stable")]
    first = np.ones(order.size, dtype=bool)
    first[1:] = target[order][1:] != target[order][:-1]
    chosen = order[first]
    keys = (np.arange(W * H, dtype=np.uint32) if prev_keys is None
            else np.asarray(prev_keys, dtype=np.uint32).reshape(-1))
    out = np.full(W * H, W * H, dtype=np.int64)
    out[target[chosen]] = keys[chosen]
    taken = np.zeros(W * H, dtype=bool)
    taken[chosen] = True
    out[out == W * H] = keys[~taken]
    return out.astype(np.uint32)


def film_shift(anchors, projected, width: int, height: int) -> Tuple[float, float]:
    """The image's screen motion from one frame to the next in film units (fractions
    of the width and height): the median displacement of the anchors that are still
    in front of the camera. (0, 0) when fewer than a quarter of them are."""
    motion = _anchor_motion(anchors, projected)
    if motion is None:
        return 0.0, 0.0
    d, ok = motion
    return float(np.median(d[ok, 0])) / width, float(np.median(d[ok, 1])) / height


def _anchor_motion(anchors, projected):
    """The anchors' raster displacement into the next frame (n, 2) and which anchors
    have one (hit something, still in front of the camera); None when fewer than a
    quarter of them do (or the two lists do not match)."""
    a = np.asarray(anchors, dtype=np.float64).reshape(-1, 6)
    p = np.asarray(projected, dtype=np.float64).reshape(-1, 2)
    if a.shape[0] == 0 or p.shape[0] != a.shape[0]:
        return None
    ok = np.isfinite(p).all(axis=1) & (a[:, 0] >= 0)
    if ok.sum() < max(1, a.shape[0] // 4):
        return None
    return p - a[:, 4:6], ok


def _key_bytes(keys) -> bytes:
    """A key map as a state file holds it (little-endian u32), b"" for none."""
    return b"" if keys is None else np.asarray(keys, dtype="<u4").tobytes()


def bootstrap_ratio(f_old, f_new) -> Optional[dict]:
    """The ratio estimator of b_{f+1}/b_f over the bootstrap points (the same points
    in both frames with stored seeds: common random numbers): R = Σ f_new / Σ f_old,
    as a ``temporal_ratio_statistics``-like dict whose ``variance / count`` is R's
    variance (delta method). None without a previous bootstrap of the same size."""
    a = np.asarray(f_old, dtype=np.float64)
    b = np.asarray(f_new, dtype=np.float64)
    if a.size < 2 or a.shape != b.shape or not a.sum() > 0:
        return None
    r = float(b.sum() / a.sum())
    var_r = float(np.sum((b - r * a) ** 2) / (a.size - 1) / a.size / a.mean() ** 2)
    return {"mean": r, "variance": var_r * a.size, "count": int(a.size), "zero": 0}


def carry_of(prev) -> Optional[dict]:
    """What the next frame's :func:`prepare_frame` reads of a frame's state (a
    FrameState or None): the screen anchors, film offset, bootstrap f* (little-endian
    float64 bytes, or an array of them) and starts."""
    if prev is None:
        return None
    keys = np.frombuffer(prev.pixel_keys, dtype="<u4") if prev.pixel_keys else None
    return {"anchors": list(prev.anchors), "film_offset": tuple(prev.film_offset),
            "pixel_keys": keys,
            "boot_f": bytes(prev.boot_f), "start_picks": list(prev.start_picks)}


def prepare_frame(core, scene, st, frame: float, config: dict,
                  prev: Optional[dict]) -> Tuple[dict, dict]:
    """The work before a frame's render (the module doc): sets the seed, pilot, film
    offset, bootstrap f* and chain starts of ``st`` for ``frame`` from the previous
    frame's :func:`carry_of` (or None). Returns (temporal record, pending: what
    :meth:`TemporalDriver.finish` and the next frame need). A pure function of its
    inputs; ``record["state_in"]`` is True when the previous state was used."""
    per_frame, carry = bool(config["per_frame"]), bool(config["carry"])
    st.seed = frame_seed(int(config["base_seed"]), frame, per_frame)
    st.film_offset_x = st.film_offset_y = 0.0
    if hasattr(st, "pixel_keys"):
        st.pixel_keys = None
    if hasattr(st, "mlt_initial_states"):
        st.mlt_initial_states = None
        st.mlt_bootstrap_f = None
    rec = {"seed": int(st.seed), "seed_per_frame": per_frame,
           "carry_states": carry, "smooth_normalization": bool(config["smooth"]),
           "state_in": None, "carried_chains": 0, "refreshed_chains": 0,
           "film_offset": [0.0, 0.0]}
    pending = {"ratio": None, "picks": [], "boot_f": None, "film_offset": (0.0, 0.0),
               "anchors": [], "pixel_keys": None}
    if config["integrator"] in MLT_INTEGRATORS and hasattr(core, "mlt_resolve_paths"):
        # what the chains render, resolved for this frame's scene as the render
        # resolves it (the bootstrap and chain counts below depend on it)
        # (from the requested value each frame: what a frame's scene allows may change)
        st.mlt_paths = config.get("mlt_paths", st.mlt_paths)
        # the start probe (--mlt-min-starts): a frame whose chains would start from a
        # handful of paths renders without chains, as the core decides for a frame it
        # is handed whole (render.cpp); decided here, before the bootstrap below
        probe = core.mlt_probe_starts(scene, st) if hasattr(core, "mlt_probe_starts") else None
        st.mlt_paths = core.mlt_resolve_paths(scene, st)
        if probe is not None:
            rec["start_probe"] = {k: probe[k] for k in ("probe", "probe_nonzero", "bootstrap",
                                                         "expected_starts", "too_few")}
            if probe["too_few"]:
                st.mlt_paths = "none"
    if config["integrator"] in MLT_INTEGRATORS and hasattr(st, "pilot"):
        # the pixel importance's pilot, rendered once for the render and for the
        # carry-over evaluations below (f* must be the same function in all of them)
        st.pilot = None
        if str(getattr(st, "importance", "luminance")) == "pixel":
            t_pilot = time.perf_counter()
            st.pilot = core.render_pilot(scene, st)
            rec["pilot_time_s"] = time.perf_counter() - t_pilot
    prev_ok = prev is not None and not per_frame
    if REPROJECT and not per_frame:
        # the film offset follows the image's median screen motion (camera, moving
        # geometry): the chains' film position (and, with PIXEL_KEYS off, the pixels'
        # sample keys) move with it, so a chain start kept from the previous frame lands
        # on the surface it saw before (in steps of whole pixels: the frame's motion
        # rounded; rounding the accumulated offset instead would move them 0 or 2 pixels
        # in some frames of a 1-pixel pan)
        offset = (0.0, 0.0)
        projected = None
        if prev_ok and prev["anchors"]:
            projected = core.temporal_project_anchors(scene, st, prev["anchors"])
            dx, dy = film_shift(prev["anchors"], projected, st.width, st.height)
            dx, dy = round(dx * st.width) / st.width, round(dy * st.height) / st.height
            offset = ((prev["film_offset"][0] + dx) % 1.0, (prev["film_offset"][1] + dy) % 1.0)
        st.film_offset_x = offset[0] if offset[0] < 1.0 else 0.0
        st.film_offset_y = offset[1] if offset[1] < 1.0 else 0.0
        pending["film_offset"] = (float(st.film_offset_x), float(st.film_offset_y))
        rec["film_offset"] = list(pending["film_offset"])
        if PIXEL_KEYS and hasattr(st, "pixel_keys"):
            # the pixels' sample keys (pt, bdpt, the direct pass, the AOVs) follow each
            # pixel's own motion (key_map): a pixel sample's numbers land on the surface
            # they saw before, near and far surfaces alike
            keys = prev.get("pixel_keys") if prev_ok else None
            if keys is not None and len(keys) != st.width * st.height:
                keys = None
            if projected is not None:
                moved = key_map(keys, prev["anchors"], projected, st.width, st.height)
                keys = moved if moved is not None else keys
            if keys is not None:
                keys = np.asarray(keys, dtype=np.uint32)
                n_moved = int(np.count_nonzero(keys != np.arange(keys.size, dtype=np.uint32)))
                rec["pixel_keys_moved"] = n_moved
                keys = keys if n_moved else None          # the identity: no map
            st.pixel_keys = keys
            pending["pixel_keys"] = keys
        pending["anchors"] = list(core.temporal_screen_anchors(scene, st, *anchor_grid(st.width, st.height)))
    if not carry:
        return rec, pending
    # the bootstrap's size: the setting's, or with bootstrap_samples 0 (auto) the size the
    # render would pick (0: temporal_bootstrap_states runs its probe) — kept from the
    # frame before where there is one, so that the frames' starts stay coupled
    n_boot = int(core.temporal_bootstrap_count(st))
    if int(getattr(st, "bootstrap_samples", 1)) == 0:
        n_boot = len(prev["boot_f"]) // 8 if prev_ok and prev.get("boot_f") else 0  # float64 bytes
    t0 = time.perf_counter()
    boot, traced = core.temporal_bootstrap_states(scene, st, n_boot)
    f_new = list(core.temporal_f_star(boot))
    # the render counts these evaluations in its budget but not their rays (as the
    # pilot's): the record says what the frame loop traced for them
    rec.update(bootstrap_rays=int(traced["rays"]), bootstrap_time_s=time.perf_counter() - t0,
               bootstrap_probe=int(traced.get("probe", 0)),
               bootstrap_probe_nonzero=int(traced.get("probe_nonzero", 0)))
    if float(getattr(st, "time_budget", 0.0) or 0.0) > 0.0:
        # the pilot and the bootstrap evaluated here are the render's work: a time
        # budget pays for them as the render's own pilot and bootstrap would
        spent = rec["bootstrap_time_s"] + rec.get("pilot_time_s", 0.0)
        st.time_budget = max(float(st.time_budget) - spent, 1e-3)
    # the render uses these values for b and does not evaluate the points again
    st.mlt_bootstrap_f = f_new
    pending["boot_f"] = f_new
    f_old: List[float] = []
    prev_picks: List[int] = []
    if prev_ok and len(prev["boot_f"]) and prev["start_picks"]:
        f_old = list(np.frombuffer(prev["boot_f"], dtype="<f8"))
        if len(f_old) == n_boot:
            prev_picks = list(prev["start_picks"])
        else:
            f_old = []
    # as many starts as the render runs chains (never the requested count itself:
    # a --chains the budget cannot feed must not allocate that many starts)
    n_chains = int(core.temporal_chain_count(st))
    c = core.temporal_couple_starts(f_old, f_new, prev_picks, n_chains,
                                    int(config["base_seed"]), frame_key(frame))
    picks = list(c["picks"])
    if picks:
        st.mlt_initial_states = core.temporal_gather_states(boot, boot, picks, 0)
    pending["picks"] = picks
    if f_old:
        pending["ratio"] = bootstrap_ratio(f_old, f_new)
    rec.update(state_in=True if prev_picks else None,
               carried_chains=int(c["kept"]), refreshed_chains=int(c["refreshed"]),
               fresh_chains=int(c["fresh"]),
               start_tv=float(c["tv"]) if prev_picks else None)
    if pending["ratio"] is not None:
        rec["ratio_mean"] = float(pending["ratio"]["mean"])
    return rec, pending


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
        self.mlt_paths = str(getattr(settings, "mlt_paths", "auto"))
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
        rec, pending = prepare_frame(self.core, scene, st, frame, self.config(),
                                     carry_of(self.prev))
        return self.adopt(st, rec, pending)

    def config(self) -> dict:
        """What :func:`prepare_frame` needs of this driver (picklable: a Dask task
        prepares a frame on a worker, cmlt.shot.distributed)."""
        return {"base_seed": self.base_seed, "per_frame": self.per_frame, "carry": self.carry,
                "smooth": self.smooth, "integrator": self.integrator, "mlt_paths": self.mlt_paths}

    def adopt(self, st, rec: dict, pending: dict) -> dict:
        """Take the result of :func:`prepare_frame` for the frame about to render
        (made here, or on a Dask worker from the same inputs); returns the record."""
        st.seed = int(rec["seed"])
        self._pending = pending
        if rec.get("state_in") is not None:
            rec["state_in"] = self.prev_source
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
        boot = np.asarray(boot, dtype=np.float64) if boot is not None else None
        if b is None:                           # no normalisation (pt, bdpt)
            norm = None
        else:
            paired = None
            if prev is not None and prev.boot_f and boot is not None and not self.per_frame:
                paired = paired_difference(np.frombuffer(prev.boot_f, dtype="<f8"), boot)
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
        picks = list(self._pending.get("picks", []))
        used = int(stats.get("chains") or 0)
        picks = picks[:used] if used else []
        boot_f = self._pending.get("boot_f")
        if boot_f is None and boot is not None and not self.carry:
            boot_f = boot                        # the paired change test only
        fs = FrameState(shot_hash=self.shot_hash, width=self.size[0], height=self.size[1],
                        integrator=self.integrator, seed=self.base_seed, frame=float(frame),
                        settings_hash=self.settings_hash, chain_count=len(picks),
                        start_picks=picks,
                        film_offset=tuple(self._pending.get("film_offset", (0.0, 0.0))),
                        anchors=list(self._pending.get("anchors", [])),
                        pixel_keys=_key_bytes(self._pending.get("pixel_keys")),
                        boot_f=np.asarray(boot_f, dtype="<f8").tobytes()
                        if boot_f is not None else b"",
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
