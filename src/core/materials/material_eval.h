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
/// opacityThreshold cutout resolved), with the hit's interpolated primvar columns
/// (SurfaceInteraction::primvars, n_primvars of them) for the inputs that read primvars.
PreviewSurfaceParams preview_params(const Material& mat, const Vec2& st,
                                    const std::vector<Texture>& textures,
                                    const float* primvars = nullptr, int n_primvars = 0);

/// The BSDF at `si` (textures at si.uv, primvar inputs from si.primvars). The shading normal is si.ns, perturbed by the material's normal map
/// when it has one and si.dpdu is known; it stays on si.ng's side.
Bsdf make_bsdf(const Material& mat, const SurfaceInteraction& si,
               const std::vector<Texture>& textures);
/// make_bsdf after the normal map: the BSDF with shading normal `ns` (geometric `ng`),
/// textures at `st`, primvar inputs from `primvars` (n_primvars of them; null: none).
Bsdf make_bsdf_at(const Material& mat, const Vec2& st, const Vec3& ns, const Vec3& ng,
                  const std::vector<Texture>& textures, const float* primvars, int n_primvars);

/// The diffuse colour (UsdPreviewSurface diffuseColor, or the Lambert colour) at texture
/// coordinate `st`, textured (and read from the hit's primvars) as make_bsdf does: what the
/// albedo AOV reports.
Spectrum diffuse_colour(const Material& mat, const Vec2& st, const std::vector<Texture>& textures,
                        const float* primvars = nullptr, int n_primvars = 0);

/// Is the BSDF make_bsdf builds for `mat` at every hit the same LambertianBsdf, with an
/// unperturbed shading normal and no emission? Then *reflectance is its colour. (Legacy
/// Lambert and diffuse-kernel preview materials without textures, primvar inputs,
/// normal map or emission.)
bool constant_lambert(const Material& mat, const std::vector<Texture>& textures, Spectrum* reflectance);

/// Sets mat->constant_bsdf to the preview model of a preview material whose model inputs
/// are all constants (textures and primvars may drive only the normal and the emission),
/// rendered by the general kernel; clears it otherwise. make_bsdf then copies it.
void prepare_constant_bsdf(Material* mat);

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
