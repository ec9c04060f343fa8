#pragma once
/// \file A material at a surface point: textures looked up at the hit's st, the normal map
/// applied, the UsdPreviewSurface model built. Used by every integrator (PT, BDPT, MLT).
#include "materials/bsdf.h"
#include "materials/material.h"
#include "scene/interaction.h"
#include "textures/texture.h"

#include <vector>

namespace cmlt {

/// UsdPreviewSurface parameters of `mat` at texture coordinate `st` (textures applied,
/// opacityThreshold cutout resolved).
PreviewSurfaceParams preview_params(const Material& mat, const Vec2& st,
                                    const std::vector<Texture>& textures);

/// The BSDF at `si`. The shading normal is si.ns, perturbed by the material's normal map
/// when it has one and si.dpdu is known; it stays on si.ng's side.
Bsdf make_bsdf(const Material& mat, const SurfaceInteraction& si,
               const std::vector<Texture>& textures);

/// The diffuse colour (UsdPreviewSurface diffuseColor, or the Lambert colour) at texture
/// coordinate `st`, textured as make_bsdf textures it: what the albedo AOV reports.
Spectrum diffuse_colour(const Material& mat, const Vec2& st, const std::vector<Texture>& textures);

/// Can a hit on `mat` let a ray through without scattering (a pass-through lobe:
/// opacityThreshold cut-out, or an ior-1 interface with opacity < 1, constant or
/// textured)? Conservative per material; Scene::transmittance evaluates the hit itself.
/// Emissive materials answer no: their pass-through lobe stays an ordinary Dirac
/// transmission (a vertex), so that BDPT's s = 0 strategy sees their emission.
bool may_pass_rays(const Material& mat);

/// Emitted radiance (two-sided) at texture coordinate `st`.
Spectrum emitted_radiance(const Material& mat, const Vec2& st,
                          const std::vector<Texture>& textures);

}  // namespace cmlt
