#pragma once
/// \file Which material kernel renders a material on a frame.
///
/// The general kernel evaluates UsdPreviewSurface in full at every hit: F0 / F90, lobe
/// flags and probabilities, Schlick terms in every eval / pdf / sample, the texture and
/// primvar look-ups of nine inputs. A material whose inputs make that model an exact
/// Lambertian on this frame — no specular lobe (F0 = 0: the specular workflow with
/// specularColor 0, or the metallic workflow with metallic 0 and ior 1), no clearcoat,
/// opaque, and none of those inputs textured or read from primvars — is rendered by the
/// diffuse-only kernel instead (LambertianBsdf with the material's diffuse colour, which
/// may still be textured or a primvar; normal maps apply as before). The two kernels give
/// the same image to float rounding and draw the same random numbers
/// (tests/python/effects/test_kernels.py); the diffuse-only one executes about a quarter
/// fewer instructions on a Lambertian Cornell box (README, "What effects cost").
///
/// Chosen at frame start (render(), RenderSettings::kernel): `auto` selects per material,
/// `general` renders every preview material through the full model (the reference).
#include "materials/material.h"

namespace cmlt {

/// The preview model is an exact Lambertian for `m` at every point (rule above). False for
/// non-preview (legacy Lambert) materials, which are Lambertian already.
bool exact_lambertian(const Material& m);

}  // namespace cmlt
