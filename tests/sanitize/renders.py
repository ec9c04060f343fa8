"""A few renders with the ASan + UBSan build of the core (``make test-sanitize``).

    LD_PRELOAD="$(g++ -print-file-name=libasan.so) $(g++ -print-file-name=libstdc++.so)" \\
    ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \\
    .venv/bin/python tests/sanitize/renders.py build/sanitize

Why the environment: the sanitized module links libasan, which must be the first
library in the process, so it is preloaded into the (uninstrumented) Python, together
with libstdc++ (which Python itself does not load: without it ASan's __cxa_throw
interceptor finds no real __cxa_throw and aborts at the first C++ exception, e.g. the
one usd-core's prim iterator raises to end a loop); CPython
and its extensions keep memory alive on purpose until exit, so leak detection is off
(the C++ suite under ctest keeps it on). Any ASan or UBSan report aborts the process
with a non-zero status.

The module comes from the sanitized build directory, not the editable install: the
package sources are copied next to it (``<build>/python/cmlt``) and imported from
there, with the editable install's import redirect taken out of ``sys.meta_path``.
Each case renders a small stage with every integrator (temporal carry-over, AOVs
and a second frame included) and checks the image is finite.
"""
import glob
import os
import shutil
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def stage_package(build: str) -> str:
    mods = glob.glob(os.path.join(build, "src", "bindings", "_core*.so"))
    if not mods:
        sys.exit(f"renders.py: no sanitized _core module under {build}/src/bindings")
    dest = os.path.join(build, "python")
    pkg = os.path.join(dest, "cmlt")
    if os.path.exists(pkg):
        shutil.rmtree(pkg)
    shutil.copytree(os.path.join(ROOT, "src", "cmlt"), pkg,
                    ignore=shutil.ignore_patterns("_core*.so", "__pycache__"))
    shutil.copy2(mods[0], pkg)
    return dest


def main(argv):
    build = os.path.abspath(argv[0] if argv else os.path.join(ROOT, "build", "sanitize"))
    dest = stage_package(build)
    sys.meta_path = [f for f in sys.meta_path if type(f).__name__ != "ScikitBuildRedirectingFinder"]
    sys.path.insert(0, dest)
    import numpy as np
    import cmlt._core as core
    from cmlt.shot.bridge import SceneBridge
    from cmlt.usd import load_frame, open_stage
    assert core.__file__.startswith(dest), core.__file__

    cases = [("sequences/cornell/shot.usda", (1, 2)), ("sequences/caustic_glass/shot.usda", (1,)),
             ("sequences/hard/degenerate/shot.usda", (1,)), ("sequences/hard/bulb_room/shot.usda", (1,)),
             ("sequences/hard/all_black/shot.usda", (1,)), ("sequences/hard/grazing/shot.usda", (1,))]
    for shot, frames in cases:
        stage = open_stage(os.path.join(ROOT, shot))
        bridge = SceneBridge(core)
        # the Metropolis integrators at the default (chains on the caustic paths, or none)
        # and with the chains on every path
        for integ, paths in (("pt", None), ("bdpt", None), ("pssmlt", "auto"), ("cmlt", "auto"),
                             ("pssmlt", "all"), ("cmlt", "all")):
            states = None
            for t in frames:
                fs = load_frame(stage, float(t), resolution=(24, 18))
                scene = bridge.update(fs)
                st = core.RenderSettings()
                st.width, st.height = fs.resolution
                st.spp, st.seed, st.threads, st.integrator = 8, 1, 2, integ
                if integ in ("pssmlt", "cmlt"):
                    st.chains, st.bootstrap_samples, st.mlt_paths = 32, 500, paths
                    if states is not None:
                        st.mlt_initial_states = core.temporal_evaluate_states(scene, st, states)
                r = core.render(scene, st)
                img = np.asarray(r.image)
                assert np.isfinite(img).all(), (shot, integ, paths, t)
                states = getattr(r, "mlt_states", None)
                print(f"{shot} frame {t} {integ}{' ' + paths if paths else ''}: mean {img.mean():.4g}",
                      flush=True)
        aov = core.render_aovs(scene, st, samples=2)
        assert all(np.isfinite(np.asarray(aov[k])).all() for k in ("albedo", "N", "Z"))
    print("sanitized renders: clean")


if __name__ == "__main__":
    main(sys.argv[1:])
