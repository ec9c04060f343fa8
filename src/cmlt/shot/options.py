"""What the command line asked for: :class:`RenderOptions` and its checks.

The settings fields of :class:`RenderOptions` are the table's
(:mod:`cmlt.settings`): one per stage setting, ``None`` meaning "flag not
given" (the stage's ``CmltRenderSettingsAPI`` value applies, else the
default), and one per machine setting (``threads``, ``packets``) with the
table's default. The other fields say how frames are written.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field, make_dataclass
from typing import Optional, Tuple

from ..io.exr import AOV_CHANNELS, COMPRESSIONS
from ..settings import FIELDS, MACHINE_FIELDS, SettingsError, check_overrides
from .errors import UsageError

__all__ = ["RenderOptions", "AOV_NAMES", "PREVIEW_FORMATS", "preview_path", "default_output",
           "SETTING_NAMES", "check_aovs_for"]

#: ``--aov`` names, in channel order
AOV_NAMES = tuple(AOV_CHANNELS)
#: ``--preview-format`` choices
PREVIEW_FORMATS = ("png", "jpg")


def preview_path(image_path: str, fmt: str = "png") -> str:
    """The preview beside an image: ``shot.0001.exr`` -> ``shot.0001.png``."""
    return os.path.splitext(image_path)[0] + "." + fmt


def default_output(shot: str) -> str:
    """``renders/<shot stem>.####.exr`` relative to the working directory."""
    stem = os.path.splitext(os.path.basename(shot))[0] or "shot"
    return os.path.join("renders", f"{stem}.####.exr")


@dataclass
class _FrameOptions:
    """The options that are not settings of the table."""

    #: (w, h) overriding the stage's UsdRender resolution; camera prim path
    resolution: Optional[Tuple[int, int]] = None
    camera: Optional[str] = None
    half: bool = False
    compression: str = "zip"
    #: colour space the EXRs are written in (None = the rendering space,
    #: ACEScg, pixels unchanged); any name/alias/interop ID of the config
    output_colorspace: Optional[str] = None
    #: OpenColorIO config (None: $OCIO, the stage's, else the built-in one)
    ocio_config: Optional[str] = None
    #: colour space of the config to render in (None: its scene_linear role;
    #: cmlt.color.rendering_space)
    rendering_space: Optional[str] = None
    #: extra EXR channels: any of AOV_NAMES (albedo, normal, depth, variance, error)
    aovs: Tuple[str, ...] = ()
    #: camera rays per pixel of the AOV pass (albedo, normal, depth)
    aov_samples: int = 4
    #: data window (x0, y0, x1, y1), half-open, inside the full frame
    crop: Optional[Tuple[int, int, int, int]] = None
    #: write a display-referred preview beside each EXR (png or jpg)
    preview: bool = False
    preview_format: str = "png"
    #: stops of exposure applied to previews only (the EXR is not scaled)
    exposure: float = 0.0
    #: OCIO display / view of previews (None: sRGB display, its default view)
    display: Optional[str] = None
    view: Optional[str] = None
    #: write DIR/state.####.bin per frame and continue from the previous frame's
    state_dir: Optional[str] = None
    #: a bad state file: warn and start fresh instead of failing
    fresh_start_on_bad_state: bool = False
    #: a frame whose scene and settings are the last rendered frame's (a held shot
    #: with stored seeds) takes that frame's render instead of repeating it
    #: (frame_job.hold_key); False renders every frame (--no-frame-hold)
    hold_frames: bool = True
    #: render the frames' parts as Dask tasks: a scheduler address or local:N
    #: (cmlt.shot.distributed); None renders in this process
    dask: Optional[str] = None
    #: part tasks per frame with --dask (0: automatic, DaskRenderer.auto_parts)
    dask_parts: int = 0
    #: a UsdRender.Settings prim path to use (husk's -R): authored as the stage's
    #: renderSettingsPrimPath in the session layer (None: the stage's own choice)
    render_settings: Optional[str] = None
    #: variant selections applied in the session layer before anything is read:
    #: ``SET=VALUE`` (every prim with the set) or ``/prim:SET=VALUE``, in order
    #: (:mod:`cmlt.usd.variants`)
    variants: Tuple[str, ...] = ()
    #: what lights a stage without lights or emissive materials: dome (white, radiance
    #: 1), headlight or dome-key (:func:`cmlt.usd.lights.default_lights`)
    default_light: str = "dome"
    #: purposes rendered besides default (husk's --purpose); () = cmlt's rule
    #: (render always, proxy where no render sibling, guide never)
    purposes: Tuple[str, ...] = ()

    def check(self) -> None:
        """Checks that need neither the stage nor the core: every setting
        given against the table (:func:`cmlt.settings.check_value`), then the
        output options."""
        try:
            check_overrides(self.overrides())
            check_overrides({f.name: getattr(self, f.name) for f in MACHINE_FIELDS})
        except SettingsError as exc:
            msg = str(exc)
            raise UsageError(msg[len("flag "):] if msg.startswith("flag ") else msg) from None
        if self.compression not in COMPRESSIONS:
            raise UsageError(f"--compression {self.compression!r}: choose one of "
                             f"{', '.join(COMPRESSIONS)}")
        for name in self.aovs:
            if name not in AOV_NAMES:
                raise UsageError(f"--aov {name!r}: unknown AOV; choose from "
                                 f"{', '.join(AOV_NAMES)}")
        if int(self.dask_parts) < 0:
            raise UsageError(f"--dask-parts {self.dask_parts}: must be 0 (automatic) "
                             "or more")
        if int(self.aov_samples) < 1:
            raise UsageError(f"--aov-samples {self.aov_samples}: must be at least 1")
        import math
        if not math.isfinite(float(self.exposure)) or abs(float(self.exposure)) > 64:
            raise UsageError(f"--exposure {self.exposure}: must be a finite number of stops "
                             "within -64..64")
        if self.preview_format not in PREVIEW_FORMATS:
            raise UsageError(f"--preview-format {self.preview_format!r}: choose one of "
                             f"{', '.join(PREVIEW_FORMATS)}")
        from ..usd.lights import DEFAULT_LIGHTS
        if self.default_light not in DEFAULT_LIGHTS:
            raise UsageError(f"--default-light {self.default_light!r}: choose one of "
                             f"{', '.join(DEFAULT_LIGHTS)}")
        from ..usd.frame import PURPOSES
        for p in self.purposes:
            if p not in PURPOSES:
                raise UsageError(f"--purpose {p!r}: choose from {', '.join(PURPOSES)}")
        from ..usd.variants import parse_variant
        for v in self.variants:
            try:
                parse_variant(v)
            except ValueError as exc:
                raise UsageError(f"--variant {exc}") from None
        if self.crop is not None:
            c = tuple(self.crop)
            if len(c) != 4 or c[0] < 0 or c[1] < 0 or c[2] <= c[0] or c[3] <= c[1]:
                raise UsageError(f"--crop {','.join(str(v) for v in c)}: expected x0,y0,x1,y1 "
                                 "with 0 <= x0 < x1 and 0 <= y0 < y1 (x1, y1 exclusive)")

    def overrides(self) -> dict:
        """Flag values by setting name, for :func:`cmlt.settings.resolve_settings`
        (the stage settings, resolution and camera; ``None``: not given)."""
        values = {f.name: getattr(self, f.name) for f in FIELDS}
        values.update(resolution=self.resolution, camera=self.camera)
        return values


def check_aovs_for(aovs, integrator: str, error_groups: int = 8) -> None:
    """The ``--aov`` checks that need the settings in force (flag, else the stage's,
    else the default), so run once the settings are resolved: ``error`` needs
    independent samples (pt, bdpt) or chain groups (pssmlt, cmlt with error_groups >= 3)."""
    from ..metrics.error_estimate import VARIANCE_INTEGRATORS
    if "error" in aovs and integrator not in VARIANCE_INTEGRATORS and int(error_groups) < 3:
        raise UsageError(f"--aov error: a per-pixel error estimate of {integrator} needs its "
                         f"chain groups (--error-groups G, G >= 3; got {int(error_groups)}): the "
                         "chains' samples are correlated")


#: the settings fields of RenderOptions, in the table's order
SETTING_NAMES = tuple(f.name for f in FIELDS + MACHINE_FIELDS)

#: What the command line asked for. The table's stage settings (``None``: flag
#: not given; precedence flag > stage > default) and machine settings
#: (``threads``: 0 = all cores; ``packets``: pt's and cmlt's packet tracing; neither
#: changes the estimator — cmlt's image not at all, pt's hits may differ in the last
#: ulp), then the options of :class:`_FrameOptions`.
RenderOptions = make_dataclass(
    "RenderOptions",
    [(f.name, Optional[type(f.default)], field(default=None)) for f in FIELDS]
    + [(f.name, type(f.default), field(default=f.default)) for f in MACHINE_FIELDS],
    bases=(_FrameOptions,),
    namespace={"__module__": __name__, "__doc__": (
        "What the command line asked for: a field per stage setting of the table "
        "(None = flag not given: the stage's value, else the default), threads and "
        "packets (the machine's; the estimator does not depend on them), and how frames "
        "are written (resolution, camera, EXR, AOV, preview and state options).")})

