#include "materials/material_eval.h"

#include <algorithm>
#include <cmath>

namespace cmlt {

namespace {

const Texture* lookup(const std::vector<Texture>& textures, int32_t id) {
    return (id >= 0 && size_t(id) < textures.size() && textures[size_t(id)].valid())
               ? &textures[size_t(id)]
               : nullptr;
}

/// A texture if the input has one, else the hit's primvar columns if the input reads them
/// and the mesh has them, else the constant.
Spectrum colour_input(const Spectrum& constant, int32_t tex, int8_t pv, const Vec2& st,
                      const std::vector<Texture>& textures, const float* primvars, int n_primvars) {
    if (const Texture* t = lookup(textures, tex)) return t->eval(st).xyz();
    if (pv >= 0 && int(pv) + 3 <= n_primvars)
        return Spectrum(primvars[pv], primvars[pv + 1], primvars[pv + 2]);
    return constant;
}

float scalar_input(float constant, int32_t tex, uint8_t channel, int8_t pv, const Vec2& st,
                   const std::vector<Texture>& textures, const float* primvars, int n_primvars) {
    if (const Texture* t = lookup(textures, tex)) return channel_of(t->eval(st), channel);
    if (pv >= 0 && int(pv) < n_primvars) return primvars[pv];
    return constant;
}

/// diffuseColor as the preview model sanitises it (PreviewSurfaceBsdf's constructor):
/// each channel clamped to [0, 1], a non-finite one the spec default.
Spectrum preview_colour(const Spectrum& c) {
    const Spectrum def = PreviewSurfaceParams().diffuse;
    auto ch = [](float v, float d) { return std::isfinite(v) ? std::clamp(v, 0.f, 1.f) : d; };
    return Spectrum(ch(c.x, def.x), ch(c.y, def.y), ch(c.z, def.z));
}

PreviewSurfaceParams constant_params(const Material& mat) {
    PreviewSurfaceParams p;
    p.diffuse = mat.diffuse;
    p.specular = mat.specular;
    p.use_specular_workflow = mat.use_specular_workflow;
    p.metallic = mat.metallic;
    p.roughness = mat.roughness;
    p.clearcoat = mat.clearcoat;
    p.clearcoat_roughness = mat.clearcoat_roughness;
    p.opacity = mat.opacity;
    p.ior = mat.ior;
    return p;
}

void apply_cutout(PreviewSurfaceParams* p, float opacity_threshold) {
    if (!(opacity_threshold > 0.f)) return;
    if (p->opacity < opacity_threshold) {
        p->opacity = 0.f;  // no surface: a pass-through interface
        p->ior = 1.f;
    } else {
        p->opacity = 1.f;
    }
}

}  // namespace

PreviewSurfaceParams preview_params(const Material& mat, const Vec2& st,
                                    const std::vector<Texture>& textures, const float* primvars,
                                    int n_primvars) {
    const float* q = primvars;
    const int n = primvars ? n_primvars : 0;
    PreviewSurfaceParams p = constant_params(mat);
    p.diffuse = colour_input(mat.diffuse, mat.tex_diffuse, mat.pv_diffuse, st, textures, q, n);
    p.specular = colour_input(mat.specular, mat.tex_specular, mat.pv_specular, st, textures, q, n);
    p.metallic = scalar_input(mat.metallic, mat.tex_metallic, mat.ch_metallic, mat.pv_metallic, st,
                              textures, q, n);
    p.roughness = scalar_input(mat.roughness, mat.tex_roughness, mat.ch_roughness,
                               mat.pv_roughness, st, textures, q, n);
    p.clearcoat = scalar_input(mat.clearcoat, mat.tex_clearcoat, mat.ch_clearcoat,
                               mat.pv_clearcoat, st, textures, q, n);
    p.clearcoat_roughness = scalar_input(mat.clearcoat_roughness, mat.tex_clearcoat_roughness,
                                         mat.ch_clearcoat_roughness, mat.pv_clearcoat_roughness,
                                         st, textures, q, n);
    p.opacity = scalar_input(mat.opacity, mat.tex_opacity, mat.ch_opacity, mat.pv_opacity, st,
                             textures, q, n);
    apply_cutout(&p, mat.opacity_threshold);
    return p;
}

Bsdf Bsdf::from_material(const Material& mat, const Vec3& ns, const Vec3& ng) {
    if (!mat.preview) return Bsdf(LambertianBsdf(mat.diffuse), ns, ng);
    if (mat.lambert_kernel) return Bsdf(LambertianBsdf(preview_colour(mat.diffuse)), ns, ng);
    PreviewSurfaceParams p = constant_params(mat);
    apply_cutout(&p, mat.opacity_threshold);
    return Bsdf(PreviewSurfaceBsdf(p), ns, ng);
}

Bsdf make_bsdf(const Material& mat, const SurfaceInteraction& si,
               const std::vector<Texture>& textures) {
    Vec3 ns = si.ns;
    if (const Texture* nt = lookup(textures, mat.tex_normal)) {
        // Tangent frame from dp/du, Gram-Schmidt against the interpolated normal.
        Vec3 t = si.dpdu - ns * dot(si.dpdu, ns);
        if (length_squared(t) > 0.f && is_finite(t)) {
            t = normalize(t);
            Vec3 b = cross(ns, t);
            Vec3 n = nt->eval(si.uv).xyz();
            Vec3 pn = t * n.x + b * n.y + ns * n.z;
            if (length_squared(pn) > 0.f && is_finite(pn)) {
                pn = normalize(pn);
                // Keep the perturbed normal on the geometric side (no inverted frames).
                if (dot(pn, si.ng) <= 1e-4f) {
                    pn = pn - si.ng * (dot(pn, si.ng) - 1e-4f);
                    pn = normalize(pn);
                }
                if (is_finite(pn)) ns = pn;
            }
        }
    }
    return make_bsdf_at(mat, si.uv, ns, si.ng, textures, si.primvars, si.n_primvars);
}

Bsdf make_bsdf_at(const Material& mat, const Vec2& st, const Vec3& ns, const Vec3& ng,
                  const std::vector<Texture>& textures, const float* primvars, int n_primvars) {
    if (!mat.preview) {
        return Bsdf(LambertianBsdf(colour_input(mat.diffuse, mat.tex_diffuse, -1, st, textures, nullptr, 0)), ns,
                    ng);
    }
    if (mat.lambert_kernel) {  // the diffuse-only kernel: only the colour varies
        return Bsdf(LambertianBsdf(preview_colour(colour_input(mat.diffuse, mat.tex_diffuse, mat.pv_diffuse, st,
                                                               textures, primvars, primvars ? n_primvars : 0))),
                    ns, ng);
    }
    if (mat.constant_bsdf) return Bsdf(*mat.constant_bsdf, ns, ng);
    return Bsdf(PreviewSurfaceBsdf(preview_params(mat, st, textures, primvars, n_primvars)), ns, ng);
}

bool constant_lambert(const Material& mat, const std::vector<Texture>& textures, Spectrum* reflectance) {
    // make_bsdf's Lambertian cases whose inputs are all constants
    const bool lambert = !mat.preview || (mat.lambert_kernel && mat.pv_diffuse < 0);
    if (!lambert || lookup(textures, mat.tex_diffuse) || lookup(textures, mat.tex_normal) || mat.is_emissive())
        return false;
    *reflectance = mat.preview ? preview_colour(mat.diffuse) : mat.diffuse;
    return true;
}

void prepare_constant_bsdf(Material* mat) {
    mat->constant_bsdf.reset();
    if (!mat->preview || mat->lambert_kernel) return;
    const int32_t tex[] = {mat->tex_diffuse,   mat->tex_specular,  mat->tex_metallic,
                           mat->tex_roughness, mat->tex_clearcoat, mat->tex_clearcoat_roughness,
                           mat->tex_opacity};
    const int8_t pv[] = {mat->pv_diffuse,   mat->pv_specular,           mat->pv_metallic,
                         mat->pv_roughness, mat->pv_clearcoat,          mat->pv_clearcoat_roughness,
                         mat->pv_opacity};
    for (int32_t t : tex)
        if (t >= 0) return;
    for (int8_t p : pv)
        if (p >= 0) return;
    // what preview_params gives at every hit when no input reads a texture or a primvar
    PreviewSurfaceParams p = constant_params(*mat);
    apply_cutout(&p, mat->opacity_threshold);
    mat->constant_bsdf.emplace(p);
}

bool may_pass_rays(const Material& mat) {
    if (!mat.preview) return false;  // Lambert: opaque
    // An emissive surface keeps crossing as a Dirac vertex: BDPT's s = 0 strategy needs
    // a vertex to see its emission (a crossed surface makes none).
    if (mat.is_emissive()) return false;
    if (mat.opacity_threshold > 0.f)  // a cut-out wherever opacity < threshold (apply_cutout)
        return mat.tex_opacity >= 0 || mat.pv_opacity >= 0 || mat.opacity < mat.opacity_threshold;
    if (mat.tex_opacity < 0 && mat.pv_opacity < 0 && !(mat.opacity < 1.f))
        return false;  // opaque everywhere
    // Transmission somewhere: a pass-through if the (sanitised) ior is 1.
    PreviewSurfaceParams p = constant_params(mat);
    p.opacity = 0.f;
    return PreviewSurfaceBsdf(p).has_pass_through();
}

Spectrum diffuse_colour(const Material& mat, const Vec2& st, const std::vector<Texture>& textures,
                        const float* primvars, int n_primvars) {
    // the Lambert material (preview == false) has no primvar inputs, as in make_bsdf
    return colour_input(mat.diffuse, mat.tex_diffuse, mat.preview ? mat.pv_diffuse : int8_t(-1), st,
                        textures, primvars, primvars ? n_primvars : 0);
}

Spectrum emitted_radiance(const Material& mat, const Vec2& st,
                          const std::vector<Texture>& textures) {
    Spectrum e = colour_input(mat.emission, mat.tex_emission, -1, st, textures, nullptr, 0);
    return {std::max(0.f, e.x), std::max(0.f, e.y), std::max(0.f, e.z)};
}

}  // namespace cmlt
