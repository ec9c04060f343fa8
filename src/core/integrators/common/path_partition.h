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
/// The class is a property of the path alone: a vertex counts as specular by its
/// material (analysis/scene_probes.h's rule, roughness < 0.2 metal, mirror or glass,
/// constant or textured), never by the lobe sampled, and pass-through crossings make no
/// vertex. So every sampling technique that makes a path (NEE or BSDF hit, every BDPT
/// strategy (s, t)) gives it the same class, MIS weights over the techniques still sum
/// to one within each class, and the two classes' estimates add up to the image with
/// no bias, whatever the rule is: the rule only decides which estimator does the work.
#include <cstdint>
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
    bool caustic(bool last_specular, bool diffuse_before, bool first_specular, int n_diffuse) const {
        return last_specular && diffuse_before && !(m_seen_through_easy && first_specular && n_diffuse == 1);
    }
    /// Are the seen-through caustics in the easy part (RenderSettings::mlt_sds "direct")?
    bool seen_through_easy() const { return m_seen_through_easy; }

private:
    std::vector<uint8_t> m_specular;  ///< per material id: may be near-specular
    PathPart m_part = PathPart::all;
    bool m_seen_through_easy = true;
};

}  // namespace cmlt
