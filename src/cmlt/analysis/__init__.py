"""What a frame calls for: the effects its scene uses (:mod:`cmlt.analysis.effects`)
and the integrator ``--integrator auto`` picks for a shot
(:mod:`cmlt.analysis.auto`). Loading the frames and building their core scenes
is the frame loop's business (:mod:`cmlt.shot.analyse`)."""
from .effects import EFFECT_NAMES, Effect, FrameEffects, analyse_frame
from .auto import AutoChoice, choose_integrator, sample_frames

__all__ = ["EFFECT_NAMES", "Effect", "FrameEffects", "analyse_frame", "AutoChoice",
           "choose_integrator", "sample_frames"]
