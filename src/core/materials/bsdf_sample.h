#pragma once
#include "math/vec.h"

namespace cmlt {

/// A sampled direction. For a Dirac lobe (`is_delta`), `f` and `pdf` carry the same
/// delta factor, so `f * |cos| / pdf` is the usual weight (pdf = the discrete probability
/// of the Dirac lobe). `is_transmission`: wi is on the other side of the geometric surface;
/// `eta` is the relative IOR crossed (eta_t / eta_i, 1 for reflection), for the path's
/// radiance-scale bookkeeping (Russian roulette).
struct BsdfSample {
    Vec3 wi;
    Spectrum f{0.f};
    float pdf = 0.f;
    bool is_delta = false;
    bool is_transmission = false;
    float eta = 1.f;
    /// Straight through an ior-1 interface (a cut-out or pass-through surface): not a
    /// scattering event for the integrators (they walk on as if the surface were not
    /// there, and shadow rays cross it through Scene::transmittance).
    bool pass_through = false;
    bool valid() const { return pdf > 0.f; }
};

}  // namespace cmlt
