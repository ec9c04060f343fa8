"""Per-frame state files: ``DIR/state.####.bin``.

Everything frame f+1 needs from frame f (its bootstrap f*, the bootstrap index
each chain started from, the normalisation history), so that a sequence can
continue in another job bit-identically (``cmlt render --frames 13:24 --state-dir DIR``
reads ``state.0012.bin``). Little-endian::

    header   8s  magic  b"CMLTSTAT"
             u32 version (STATE_VERSION)
             u64 shot hash          (first 8 bytes of sha256(absolute shot path))
             u32 width, u32 height
             16s integrator         (ASCII, NUL padded)
             u64 seed               (the shot seed, not a per-frame one)
             u64 chain count        (chain states in the payload)
             f64 frame              (the frame that wrote it)
             u64 settings hash      (sha256 of every setting that changes the chains)
             u64 payload length
    payload  u64 q | q × f64        f* of the bootstrap points in this frame, by index
                                    (the next frame's chain-start coupling and paired
                                    change test; stored seeds make them the same points)
             u64 n | n × u32        bootstrap index each chain started this frame from
             2 × f64                the chains' film offset (x, y) in this frame
             u64 a | a × (i32 + 5 × f32)  screen anchors (instance, object-space x, y,
                                    z, raster x, y; the core's own types — version 3:
                                    6 × f64): the next frame's screen motion
             u64 m | m bytes        the pixels' sample keys (version 4; m = 0: none):
                                    zlib of the W·H u32 (key − pixel index) mod 2³²
             u32 k | k × record     normalisation history, oldest first (see below)
    trailer  u32 CRC-32 (zlib) of header + payload

record = 15 × f64 (frame, b_fresh, s_fresh, b_ratio, s_ratio, b_combined,
s_combined, b_smoothed, s_smoothed, b_used, s_used, delta, s_delta, cusum_up,
cusum_down) + u8 change.

The frame loop always goes through these bytes, also when it keeps the state
in memory between frames of one job, so a split sequence sees exactly the
values a single job sees.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import struct
import zlib
from dataclasses import dataclass, field
from typing import List, Optional

import numpy as np

from .normalization import NormRecord

__all__ = ["STATE_MAGIC", "STATE_VERSION", "StateError", "FrameState", "encode_state",
           "decode_state", "read_state", "write_state", "state_path", "shot_hash",
           "settings_hash", "HISTORY_LIMIT"]

STATE_MAGIC = b"CMLTSTAT"
STATE_VERSION = 4
#: versions this cmlt reads (3: before the pixels' key maps)
READ_VERSIONS = (3, 4)
#: normalisation records kept (oldest dropped)
HISTORY_LIMIT = 256

_HEADER = struct.Struct("<8sIQII16sQQdQQ")
_RECORD = struct.Struct("<15dB")
_REC_FIELDS = ("frame", "b_fresh", "s_fresh", "b_ratio", "s_ratio", "b_combined", "s_combined",
               "b_smoothed", "s_smoothed", "b_used", "s_used", "delta", "s_delta",
               "cusum_up", "cusum_down")


class StateError(ValueError):
    """A state file that cannot be used; the message is one line naming the
    file and what is wrong."""


@dataclass
class FrameState:
    shot_hash: int
    width: int
    height: int
    integrator: str
    seed: int
    frame: float
    settings_hash: int
    chain_count: int = 0
    #: bootstrap index of each chain's start this frame
    start_picks: List[int] = field(default_factory=list)
    #: f* of the frame's bootstrap points by index (float64, little-endian)
    boot_f: bytes = b""
    #: the chains' film offset in this frame
    film_offset: tuple = (0.0, 0.0)
    #: flat screen anchors, 6 numbers each (core temporal_screen_anchors)
    anchors: List[float] = field(default_factory=list)
    #: the pixels' sample keys this frame (W·H little-endian u32), b"": none
    pixel_keys: bytes = b""
    history: List[NormRecord] = field(default_factory=list)

    @property
    def last(self) -> Optional[NormRecord]:
        return self.history[-1] if self.history else None


#: a screen anchor as version 4 stores it: the core's own types (instance id, floats)
_ANCHOR = np.dtype([("instance", "<i4"), ("values", "<f4", (5,))])


def _anchor_bytes(anchors) -> bytes:
    """Flat anchors (6 numbers each) as version 4's records; the core's anchors are
    int32 and float32, so nothing is lost."""
    a = np.asarray(anchors, dtype=np.float64).reshape(-1, 6)
    rec = np.empty(a.shape[0], dtype=_ANCHOR)
    rec["instance"] = a[:, 0].astype(np.int32)
    rec["values"] = a[:, 1:].astype(np.float32)
    return rec.tobytes()


def shot_hash(shot: str) -> int:
    return int.from_bytes(hashlib.sha256(os.path.abspath(shot).encode("utf-8")).digest()[:8],
                          "little")


def settings_hash(values: dict) -> int:
    text = json.dumps(values, sort_keys=True, default=str)
    return int.from_bytes(hashlib.sha256(text.encode("utf-8")).digest()[:8], "little")


def state_path(state_dir: str, frame: float) -> str:
    """``DIR/state.0012.bin``; fractional frames ``DIR/state.0012.500.bin``."""
    f = float(frame)
    if f == int(f):
        name = f"state.{int(f):04d}.bin" if f >= 0 else f"state.-{int(-f):04d}.bin"
    else:
        name = f"state.{f:08.3f}.bin"
    return os.path.join(state_dir, name)


def encode_state(s: FrameState) -> bytes:
    hist = list(s.history)[-HISTORY_LIMIT:]
    payload = bytearray()
    if len(s.boot_f) % 8:
        raise ValueError("FrameState.boot_f: not a float64 array")
    payload += struct.pack("<Q", len(s.boot_f) // 8) + bytes(s.boot_f)
    payload += struct.pack("<Q", len(s.start_picks))
    payload += struct.pack(f"<{len(s.start_picks)}I", *s.start_picks)
    payload += struct.pack("<2d", float(s.film_offset[0]), float(s.film_offset[1]))
    if len(s.anchors) % 6:
        raise ValueError("FrameState.anchors: not 6 numbers per anchor")
    payload += struct.pack("<Q", len(s.anchors) // 6)
    payload += _anchor_bytes(s.anchors)
    if s.pixel_keys:
        if len(s.pixel_keys) != 4 * s.width * s.height:
            raise ValueError("FrameState.pixel_keys: not W*H u32 keys")
        keys = np.frombuffer(s.pixel_keys, dtype="<u4")
        delta = (keys - np.arange(keys.size, dtype=np.uint32)).astype("<u4")
        packed = zlib.compress(delta.tobytes(), 6)
    else:
        packed = b""
    payload += struct.pack("<Q", len(packed)) + packed
    payload += struct.pack("<I", len(hist))
    for r in hist:
        payload += _RECORD.pack(*(float(getattr(r, k)) for k in _REC_FIELDS), 1 if r.change else 0)
    integ = s.integrator.encode("ascii")[:16]
    header = _HEADER.pack(STATE_MAGIC, STATE_VERSION, s.shot_hash, s.width, s.height, integ,
                          s.seed, s.chain_count, float(s.frame), s.settings_hash, len(payload))
    body = header + bytes(payload)
    return body + struct.pack("<I", zlib.crc32(body) & 0xFFFFFFFF)


def decode_state(data: bytes, path: str = "<state>") -> FrameState:
    """Parse a state file's bytes; :class:`StateError` names ``path``."""
    def bad(what: str) -> StateError:
        return StateError(f"{path}: {what}")

    if len(data) < len(STATE_MAGIC) or data[:len(STATE_MAGIC)] != STATE_MAGIC:
        raise bad("not a cmlt state file (bad magic)")
    if len(data) < _HEADER.size:
        raise bad(f"truncated state file ({len(data)} bytes, the header alone is {_HEADER.size})")
    (_, version, sh, w, h, integ, seed, count, frame, seth, plen) = _HEADER.unpack_from(data, 0)
    if version not in READ_VERSIONS:
        raise bad(f"state format version {version}, this cmlt reads versions "
                  f"{', '.join(map(str, READ_VERSIONS))}")
    want = _HEADER.size + plen + 4
    if len(data) < want:
        raise bad(f"truncated state file ({len(data)} of {want} bytes)")
    if len(data) > want:
        raise bad(f"trailing bytes after the state ({len(data)} bytes, expected {want})")
    (crc,) = struct.unpack_from("<I", data, want - 4)
    if zlib.crc32(data[:want - 4]) & 0xFFFFFFFF != crc:
        raise bad("checksum mismatch (the state file is corrupted)")
    out = FrameState(shot_hash=sh, width=w, height=h,
                     integrator=integ.rstrip(b"\0").decode("ascii", "replace"), seed=seed,
                     frame=frame, settings_hash=seth, chain_count=count)
    p = _HEADER.size
    try:
        (q,) = struct.unpack_from("<Q", data, p); p += 8
        if p + 8 * q > len(data):
            raise struct.error("bootstrap values run past the end")
        out.boot_f = bytes(data[p:p + 8 * q]); p += 8 * q
        (n,) = struct.unpack_from("<Q", data, p); p += 8
        if p + 4 * n > len(data):
            raise struct.error("chain starts run past the end")
        out.start_picks = list(struct.unpack_from(f"<{n}I", data, p)); p += 4 * n
        if any(i >= q for i in out.start_picks):
            raise struct.error("a chain start is not a bootstrap index")
        out.film_offset = struct.unpack_from("<2d", data, p); p += 16
        (a,) = struct.unpack_from("<Q", data, p); p += 8
        size = (48 if version < 4 else _ANCHOR.itemsize) * a
        if p + size > len(data):
            raise struct.error("screen anchors run past the end")
        if version < 4:
            out.anchors = list(struct.unpack_from(f"<{6 * a}d", data, p))
        else:
            rec = np.frombuffer(data, dtype=_ANCHOR, count=a, offset=p)
            flat = np.empty((a, 6), dtype=np.float64)
            flat[:, 0] = rec["instance"]
            flat[:, 1:] = rec["values"]
            out.anchors = flat.ravel().tolist()
        p += size
        if version >= 4:
            (m,) = struct.unpack_from("<Q", data, p); p += 8
            if p + m > len(data):
                raise struct.error("pixel keys run past the end")
            if m:
                try:
                    raw = zlib.decompress(bytes(data[p:p + m]))
                except zlib.error:
                    raise struct.error("pixel keys do not decompress") from None
                if len(raw) != 4 * w * h:
                    raise struct.error(f"{len(raw) // 4} pixel keys for {w}x{h} pixels")
                keys = (np.frombuffer(raw, dtype="<u4") + np.arange(w * h, dtype=np.uint32)).astype("<u4")
                if not np.array_equal(np.sort(keys), np.arange(w * h, dtype=np.uint32)):
                    raise struct.error("the pixel keys are not a permutation")
                out.pixel_keys = keys.tobytes()
            p += m
        (k,) = struct.unpack_from("<I", data, p); p += 4
        for _ in range(k):
            vals = _RECORD.unpack_from(data, p); p += _RECORD.size
            rec = NormRecord(**dict(zip(_REC_FIELDS, vals[:15])), change=bool(vals[15]))
            out.history.append(rec)
    except struct.error as exc:
        raise bad(f"malformed payload ({exc})") from None
    if p != want - 4:
        raise bad("malformed payload (length does not match its contents)")
    return out


def read_state(path: str) -> FrameState:
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except FileNotFoundError:
        raise StateError(f"{path}: no such state file") from None
    except OSError as exc:
        raise StateError(f"{path}: cannot read: {exc.strerror or exc}") from None
    return decode_state(data, path)


def write_state(path: str, data: bytes) -> str:
    """Write encoded state bytes atomically (temporary name + rename)."""
    from ..io.atomic import atomic_path

    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with atomic_path(path) as tmp:          # the temporary is removed on failure
        with open(tmp, "wb") as fh:
            fh.write(data)
    return path


def check_compatible(s: FrameState, path: str, *, shot_hash_: int, width: int, height: int,
                     integrator: str, seed: int, settings_hash_: int, frame: float) -> None:
    """:class:`StateError` if the state was written for something else."""
    def bad(what: str) -> StateError:
        return StateError(f"{path}: {what}")
    if s.shot_hash != shot_hash_:
        raise bad("written for a different shot")
    if (s.width, s.height) != (width, height):
        raise bad(f"written at {s.width}x{s.height}, this render is {width}x{height}")
    if s.integrator != integrator:
        raise bad(f"written by integrator {s.integrator!r}, this render uses {integrator!r}")
    if s.seed != seed:
        raise bad(f"written with seed {s.seed}, this render uses seed {seed}")
    if s.settings_hash != settings_hash_:
        raise bad("written with different render settings (spp, chains, sigma, ... differ)")
    if not math.isclose(s.frame, frame):
        raise bad(f"holds frame {s.frame:g}, expected frame {frame:g}")
