#pragma once
/// \file Material table rows (rendering-space linear RGB): every UsdPreviewSurface input,
/// each either a constant or a texture (UsdUVTexture) looked up at the hit's st.
///
/// `preview == false` is the legacy Lambert material (diffuse + emission only), what
/// `Scene.set_materials(diffuse, emission)` without `params` builds; `preview == true` uses
/// materials/preview_surface.h with every field below.
///
/// Textured inputs: `tex_*` is a texture id (Scene::add_texture) or -1; scalar inputs read
/// channel `ch_*` (0..3 = r, g, b, a: the UsdUVTexture output the input is connected to).
/// A texture replaces the constant (the constant is the fallback the reader already
/// resolved). `tex_normal` is a tangent-space normal map (after scale/bias, in [-1, 1]^3,
/// +z along the shading normal, +x along dp/du).
///
/// Primvar inputs (UsdPrimvarReader_*): `pv_*` is the first column of the hit's interpolated
/// primvars (SurfaceInteraction::primvars, from MeshData::primvars) or -1; a colour input
/// reads 3 columns from there, a scalar input 1. A hit whose mesh has too few columns keeps
/// the constant (the reader's fallback). A texture wins over a primvar on the same input.
/// Emission is never read from primvars (triangle lights sample a constant or a texture).
///
/// opacityThreshold > 0 turns opacity into a cutout (UsdPreviewSurface spec): opacity below
/// the threshold is no surface at all (an ior-1 pass-through), anything else is opaque.
/// Otherwise (1 - opacity) weights the dielectric (glass) lobe with `ior`.
#include "materials/preview_surface.h"
#include "math/vec.h"

#include <cstdint>
#include <optional>

namespace cmlt {

struct Material {
    Spectrum diffuse{0.18f, 0.18f, 0.18f};
    Spectrum emission{0.f, 0.f, 0.f};
    bool preview = false;  ///< false: Lambert(diffuse) only (backward compatible)
    Spectrum specular{0.f, 0.f, 0.f};
    bool use_specular_workflow = false;
    float metallic = 0.f;
    float roughness = 0.5f;
    float clearcoat = 0.f;
    float clearcoat_roughness = 0.01f;
    float opacity = 1.f;
    float opacity_threshold = 0.f;
    float ior = 1.5f;

    int32_t tex_diffuse = -1, tex_emission = -1, tex_specular = -1, tex_normal = -1;
    int32_t tex_metallic = -1, tex_roughness = -1, tex_clearcoat = -1,
            tex_clearcoat_roughness = -1, tex_opacity = -1;
    uint8_t ch_metallic = 0, ch_roughness = 0, ch_clearcoat = 0, ch_clearcoat_roughness = 0,
            ch_opacity = 3;
    int8_t pv_diffuse = -1, pv_specular = -1, pv_metallic = -1, pv_roughness = -1,
           pv_clearcoat = -1, pv_clearcoat_roughness = -1, pv_opacity = -1;

    /// Rendered by the diffuse-only kernel: a preview material that is an exact
    /// Lambertian on this frame (analysis/kernel_select.h); set per render by the core,
    /// never by the caller. The image is the preview model's to float rounding.
    bool lambert_kernel = false;
    /// The preview model of a material none of whose model inputs varies over the surface
    /// (no texture or primvar drives them): built once per render by the core
    /// (Scene::select_kernels, materials/material_eval.h prepare_constant_bsdf) and copied
    /// at every hit instead of rebuilt from the inputs; the same object, so the same
    /// image. Empty otherwise, and for the Lambert kernels.
    std::optional<PreviewSurfaceBsdf> constant_bsdf{};

    bool is_emissive() const { return max_component(emission) > 0.f || tex_emission >= 0; }
};

/// Column layout of the float32 (K, P) `params` table of `Scene.set_materials`
/// (P = k_param_cols_basic without textures, k_param_cols_full with them, or
/// k_param_cols_primvar with primvar inputs too). Texture columns hold a texture id or -1;
/// channel columns 0..3 (r, g, b, a); primvar columns a first primvar column or -1.
namespace material_col {
constexpr int specular_r = 0, specular_g = 1, specular_b = 2, use_specular_workflow = 3,
              metallic = 4, roughness = 5, clearcoat = 6, clearcoat_roughness = 7, opacity = 8,
              opacity_threshold = 9, ior = 10;
constexpr int tex_diffuse = 11, tex_emission = 12, tex_specular = 13, tex_normal = 14,
              tex_metallic = 15, tex_roughness = 16, tex_clearcoat = 17,
              tex_clearcoat_roughness = 18, tex_opacity = 19;
constexpr int ch_metallic = 20, ch_roughness = 21, ch_clearcoat = 22, ch_clearcoat_roughness = 23,
              ch_opacity = 24;
constexpr int pv_diffuse = 25, pv_specular = 26, pv_metallic = 27, pv_roughness = 28,
              pv_clearcoat = 29, pv_clearcoat_roughness = 30, pv_opacity = 31;
}  // namespace material_col
constexpr int k_param_cols_basic = 11;
constexpr int k_param_cols_full = 25;
constexpr int k_param_cols_primvar = 32;

}  // namespace cmlt
