#pragma once
/// \file A partition of path space into the paths a path tracer samples well and the
/// caustic paths it does not, so that the Metropolis integrators can render only the
/// second kind with their chains and the first with independent path-traced samples
/// (RenderSettings::mlt_paths = "caustics"; mlt/mlt_context.h, mlt/direct_pass.h).
///
/// A path x0 (camera) x1 … xk x_{k+1} (on a light) with k ≥ 1 scattering vertices is a
/// *caustic path* when its last scattering vertex xk (the one next to the light) is on a
/// material that can be near-specular, and some earlier scattering vertex x1 … x_{k−1}
/// is on one that cannot: light reaches a rough surface only through a specular chain,
/// L S+ D (S|D)* E in Heckbert's notation. Next-event estimation cannot sample the
/// S-to-light edge, and BSDF sampling from the rough vertex must hit the light through
/// the specular chain: the paths a path tracer finds rarely. Every other path (emitters
/// seen directly or through mirrors, direct and indirect diffuse light, glossy
/// reflections of lit surfaces) it samples well.
///
/// Seen-through caustics. A caustic the camera sees through a near-specular chain,
/// E S+ D S+ L (x1, the vertex the camera sees, near-specular; exactly one rough vertex),
/// goes to the easy part by default (RenderSettings::mlt_sds "direct"; "chains" keeps it
/// with the caustic part).
/// BDPT makes such a path with one strategy only, the camera subpath that hits the light.
/// Behind curved glass and with a small light (sequences/caustic_glass: the floor's
/// caustic seen through the ball that throws it) a chain on such a path can sit on an
/// island of primary sample space: moving the film position or the rough vertex's
/// direction loses the light behind the chain, almost every proposal has f* = 0, and the
/// chain stays for the frame. The island then keeps the share of the chains' image its
/// start had, f*_i / Σ f* over the bootstrap — a plain Monte Carlo estimate of its light
/// from a few hundred thousand bootstrap samples, where the direct pass has millions; no
/// choice of f* or of the kernel changes that. In the direct pass those paths are the
/// path tracer's (BSDF-sampled hits of the light through the chain): the expected error
/// falls 16-38x on caustic_glass and on the held-out sequences/hard/caustic_sds, the
/// typical frame's rises 1.6-45x (where the chains do not get stuck they do better);
/// tests/bench/results/seen_through_caustics.md.
///
/// Light-traced caustics. A caustic path whose vertex next to the light, z_{n−1},
/// scattered by a Dirac lobe, whose first vertex z1 did not, and whose light is one the
/// direct pass's caustic light tracing traces (path/caustic_light_tracing.h: finite,
/// non-Dirac lights, when it is active) goes to the easy part by default
/// (RenderSettings::mlt_traced_caustics "direct", set_traced): the direct pass then
/// renders it as the pt integrator does, camera paths MIS-weighted against light paths
/// connected to the lens. On the stages where the chains rendered such paths the
/// path tracer with light tracing had 2-20x less error at equal evaluations
/// (tests/bench/results/chains_against_caustic_light_tracing.md); the chains keep what
/// it cannot trace — dome and distant lights behind a Dirac chain, glossy chains, paths
/// whose first vertex is Dirac. Whether a vertex scattered by a Dirac lobe is part of
/// the path (the Dirac and the non-Dirac lobes of one material make paths of different
/// measures): every technique that makes the path knows it (a BSDF-sampled vertex its
/// lobe; a connection's end is never Dirac), so the class stays a property of the path.
///
/// The class is a property of the path alone: a vertex counts as specular by its
/// material (analysis/scene_probes.h's rule, roughness < 0.2 metal, mirror or glass,
/// constant or textured), never by the lobe sampled, and pass-through crossings make no
/// vertex. So every sampling technique that makes a path (NEE or BSDF hit, every BDPT
/// strategy (s, t)) gives it the same class, MIS weights over the techniques still sum
/// to one within each class, and the two classes' estimates add up to the image with
/// no bias, whatever the rule is: the rule only decides which estimator does the work.
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace cmlt {

class Scene;

/// Which class of paths an estimator renders.
enum class PathPart : uint8_t { all, easy, caustic };

class PathPartition {
public:
    PathPartition() = default;  ///< every path
    /// `seen_through_easy`: the seen-through caustics E S+ D S+ L go to the easy part.
    PathPartition(const Scene& scene, PathPart part, bool seen_through_easy = true);

    PathPart part() const { return m_part; }
    /// `p` if it leaves some paths out, else null (no partition, or PathPart::all): what
    /// the tracers keep, so that a null check is their whole test for "every path".
    static const PathPartition* restricting(const PathPartition* p) {
        return p && p->m_part != PathPart::all ? p : nullptr;
    }
    /// Is a surface vertex on this material a specular one (S) of the rule?
    bool specular(uint32_t material_id) const {
        return material_id < m_specular.size() && m_specular[material_id] != 0;
    }
    /// Does the estimator render a path of this class?
    bool wants(bool caustic) const {
        return m_part == PathPart::all || (m_part == PathPart::caustic) == caustic;
    }

    /// The class from the scattering vertices: `last_specular` (the vertex next to the
    /// light) and `diffuse_before` (any rough vertex before it) make a caustic path, less
    /// the seen-through caustics (E S+ D S+ L: `first_specular`, the vertex the camera sees, near-specular
    /// and `n_diffuse`, the rough vertices, exactly 1; any count above 1 reads as more) where the rule
    /// gives those to the easy part (the file comment).
    /// `traced`: the path is a light-traced caustic one the easy part takes (traced()).
    bool caustic(bool last_specular, bool diffuse_before, bool first_specular, int n_diffuse,
                 bool traced = false) const {
        return last_specular && diffuse_before && !(m_seen_through_easy && first_specular && n_diffuse == 1) &&
               !traced;
    }
    /// Is a path ending on light `light` (a Scene light index, -1: none) a light-traced
    /// caustic one that goes to the easy part: z_{n−1} scattered by a Dirac lobe
    /// (`last_dirac`), z1 not (`first_dirac`), the light traced (set_traced)?
    bool traced(bool first_dirac, bool last_dirac, int32_t light) const {
        return last_dirac && !first_dirac && light >= 0 && size_t(light) < m_traced.size() &&
               m_traced[size_t(light)] != 0;
    }
    /// The lights the direct pass's caustic light tracing traces, per Scene light index
    /// (CausticLightTracing::traced_lights); empty (the default): no path is a
    /// light-traced caustic one (RenderSettings::mlt_traced_caustics "chains", or
    /// nothing traced).
    void set_traced(std::vector<uint8_t> traced_lights) { m_traced = std::move(traced_lights); }
    /// Are any light-traced caustics in the easy part?
    bool has_traced() const { return !m_traced.empty(); }
    /// Are the seen-through caustics in the easy part (RenderSettings::mlt_sds "direct")?
    bool seen_through_easy() const { return m_seen_through_easy; }

private:
    std::vector<uint8_t> m_specular;  ///< per material id: may be near-specular
    PathPart m_part = PathPart::all;
    bool m_seen_through_easy = true;
    std::vector<uint8_t> m_traced;  ///< per light index: traced (set_traced)
};

}  // namespace cmlt
