// Bindings of the temporal carry-over (src/core/temporal/carry.h): the bootstrap points
// of a frame, the coupled chain starts, screen anchors, and states evaluated in a frame.
// The GIL is released while paths are traced.
#include "bind_common.h"

#include "integrators/mlt/chain_state.h"
#include "scene/scene.h"
#include "temporal/carry.h"
#include "util/error.h"

#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

namespace cmlt::bindings {

using namespace nb::literals;

namespace {

void prepare(Scene& scene, const RenderSettings& settings, const char* fn) {
    settings.validate();
    if (!scene.has_camera()) CMLT_THROW(SceneError, fn << ": the scene has no camera (call set_camera)");
    if (scene.dirty()) scene.commit();
}

}  // namespace

void bind_temporal(nb::module_& m) {
    m.def(
        "temporal_evaluate_states",
        [](Scene& scene, const RenderSettings& settings, const mlt::ChainStates& states) {
            prepare(scene, settings, "temporal_evaluate_states");
            nb::gil_scoped_release release;
            return temporal::evaluate_states(scene, settings, states);
        },
        "scene"_a, "settings"_a, "states"_a,
        "Evaluate chain states (MltStates) in this frame's scene: the completed states with "
        "this frame's f_star and colour (temporal/carry.h).");
    m.def(
        "temporal_f_star", [](const mlt::ChainStates& s) {
            std::vector<double> f;
            f.reserve(s.chains.size());
            for (const auto& c : s.chains) f.push_back(c.f_star);
            return f;
        },
        "states"_a, "f_star of every state, in order (list of float).");
    m.def(
        "temporal_ratio_statistics",
        [](const std::vector<double>& f_old, const std::vector<double>& f_new) {
            const temporal::RatioStats r = temporal::ratio_statistics(f_old, f_new);
            nb::dict d;
            d["count"] = r.count;
            d["mean"] = r.mean;
            d["variance"] = r.variance;
            d["zero"] = r.zero;
            return d;
        },
        "f_old"_a, "f_new"_a, "Mean and variance of f_new/f_old over states with f_old > 0.");
    m.def(
        "temporal_concat_states",
        [](const mlt::ChainStates& a, const mlt::ChainStates& b) {
            if (!a.chains.empty() && !b.chains.empty() && a.path_sampler != b.path_sampler)
                throw SettingsError("temporal_concat_states: states of the '" + a.path_sampler +
                                    "' and '" + b.path_sampler + "' path samplers");
            auto out = std::make_shared<mlt::ChainStates>(a);
            if (out->chains.empty()) out->path_sampler = b.path_sampler;
            out->chains.insert(out->chains.end(), b.chains.begin(), b.chains.end());
            return out;
        },
        "a"_a, "b"_a, "The states of a followed by those of b (ids kept).");
    m.def("temporal_bootstrap_count", &temporal::bootstrap_count, "settings"_a,
          "Bootstrap samples a render with these settings evaluates.");
    m.def("temporal_chain_count", &temporal::chain_count, "settings"_a,
          "Chains a render with these settings starts (at most settings.chains; 0 for pt, bdpt).");
    m.def(
        "temporal_bootstrap_states",
        [](Scene& scene, const RenderSettings& settings, uint64_t count) {
            prepare(scene, settings, "temporal_bootstrap_states");
            PathCounters c;
            std::shared_ptr<mlt::ChainStates> states;
            uint64_t probe = 0, probe_nonzero = 0;
            {
                nb::gil_scoped_release release;
                states = temporal::bootstrap_states(scene, settings, count, &c, &probe, &probe_nonzero);
            }
            nb::dict d;
            d["rays"] = c.rays;
            d["samples"] = c.samples;
            d["probe"] = probe;
            d["probe_nonzero"] = probe_nonzero;
            return nb::make_tuple(states, d);
        },
        "scene"_a, "settings"_a, "count"_a,
        "The render's bootstrap points 0..count-1 evaluated in this frame's scene: (MltStates "
        "with f_star = f*, {'rays', 'samples', 'probe', 'probe_nonzero'}: traced, and the auto "
        "size's probe samples and those carrying light (0 when none ran); temporal/carry.h). count 0: as many as "
        "the render would evaluate (bootstrap_samples 0, auto: sized by a probe).");
    m.def(
        "temporal_couple_starts",
        [](const std::vector<double>& f_old, const std::vector<double>& f_new,
           const std::vector<uint64_t>& prev_picks, uint64_t n, uint64_t seed, uint32_t frame_key) {
            const temporal::CoupledStarts c = temporal::couple_starts(f_old, f_new, prev_picks, n, seed, frame_key);
            nb::dict d;
            d["picks"] = c.picks;
            d["kept"] = c.kept;
            d["refreshed"] = c.refreshed;
            d["fresh"] = c.fresh;
            d["tv"] = c.tv;
            return d;
        },
        "f_old"_a, "f_new"_a, "prev_picks"_a, "n"_a, "seed"_a, "frame_key"_a,
        "Chain starts (bootstrap indices) of a frame coupled to the previous frame's "
        "(temporal/carry.h couple_starts): dict picks, kept, refreshed, fresh, tv.");
    m.def("temporal_keyed_uniform", &temporal::keyed_uniform, "seed"_a, "domain"_a, "id"_a, "counter"_a);
    m.def(
        "temporal_screen_anchors",
        [](Scene& scene, const RenderSettings& settings, int n_x, int n_y) {
            prepare(scene, settings, "temporal_screen_anchors");
            std::vector<temporal::Anchor> a;
            {
                nb::gil_scoped_release release;
                a = temporal::screen_anchors(scene, settings, n_x, n_y);
            }
            std::vector<double> flat;
            flat.reserve(a.size() * 6);
            for (const auto& x : a) {
                flat.insert(flat.end(), {double(x.instance), double(x.p_object.x), double(x.p_object.y),
                                         double(x.p_object.z), double(x.p_raster.x), double(x.p_raster.y)});
            }
            return flat;
        },
        "scene"_a, "settings"_a, "n_x"_a, "n_y"_a,
        "First hits of an n_x x n_y grid of camera rays as a flat list of (instance or -1, "
        "object-space x, y, z, raster x, y) per grid cell, row by row (temporal/carry.h).");
    m.def(
        "temporal_project_anchors",
        [](Scene& scene, const RenderSettings& settings, const std::vector<double>& flat) {
            prepare(scene, settings, "temporal_project_anchors");
            if (flat.size() % 6) throw std::invalid_argument("temporal_project_anchors: 6 numbers per anchor");
            std::vector<temporal::Anchor> a(flat.size() / 6);
            for (size_t i = 0; i < a.size(); ++i) {
                a[i].instance = int32_t(flat[6 * i]);
                a[i].p_object = Vec3(float(flat[6 * i + 1]), float(flat[6 * i + 2]), float(flat[6 * i + 3]));
                a[i].p_raster = Vec2(float(flat[6 * i + 4]), float(flat[6 * i + 5]));
            }
            const std::vector<Vec2> r = temporal::project_anchors(scene, settings, a);
            std::vector<double> out;
            out.reserve(2 * r.size());
            for (const Vec2& v : r) out.insert(out.end(), {double(v.x), double(v.y)});
            return out;
        },
        "scene"_a, "settings"_a, "anchors"_a,
        "Raster positions (flat x, y per anchor; NaN: gone or behind the camera) of anchors "
        "from temporal_screen_anchors in this frame's scene.");
    m.def("temporal_systematic_resample", &temporal::systematic_resample, "weights"_a, "n"_a, "u0"_a);
    m.def("temporal_gather_states", &temporal::gather_states, "carried"_a, "pool"_a, "picks"_a,
          "pool_id_base"_a, "States picked from carried (index < len) and pool (index - len).");
}

}  // namespace cmlt::bindings
