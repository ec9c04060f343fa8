// Uniform refinement of subdivision surfaces with OpenSubdiv's Far layer (see
// subdivision.h). Steps: USD's crease chains become OpenSubdiv crease edges; a
// TopologyRefiner is built from a TopologyDescriptor and refined uniformly; the points,
// the vertex data and the face-varying channels are interpolated level by level with a
// PrimvarRefiner; the last level's vertices are projected to the limit surface, whose
// tangents give the normals; the last level's faces keep a link to their authored face.
#include "geometry/subdivision.h"

#include "util/error.h"

#include <opensubdiv/far/error.h>
#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/topologyDescriptor.h>

#include <algorithm>
#include <cmath>
#include <memory>

namespace cmlt {

namespace {

using namespace OpenSubdiv;

/// OpenSubdiv reports errors through a callback (printing to stderr by default): keep the
/// last message of this thread for the exception instead.
thread_local std::string t_osd_error;

void osd_error(Far::ErrorType, const char* message) { t_osd_error = message ? message : ""; }

/// A view of `width` doubles: what PrimvarRefiner's templates interpolate.
struct Elem {
    double* p;
    int width;
    void Clear(void* = nullptr) {
        for (int k = 0; k < width; ++k) p[k] = 0.0;
    }
    void AddWithWeight(const Elem& src, float w) {
        for (int k = 0; k < width; ++k) p[k] += double(w) * src.p[k];
    }
};

/// A buffer of elements (`operator[]` hands out views).
struct Buffer {
    std::vector<double> data;
    int width = 0;
    Buffer(size_t n, int w) : data(n * size_t(w), 0.0), width(w) {}
    Elem operator[](int i) const {
        return Elem{const_cast<double*>(data.data()) + size_t(i) * size_t(width), width};
    }
};

Sdc::SchemeType scheme_type(SubdivScheme s) {
    switch (s) {
        case SubdivScheme::loop: return Sdc::SCHEME_LOOP;
        case SubdivScheme::bilinear: return Sdc::SCHEME_BILINEAR;
        default: return Sdc::SCHEME_CATMARK;
    }
}

Sdc::Options sdc_options(const SubdivInput& in) {
    Sdc::Options o;
    switch (in.boundary) {
        case SubdivBoundary::none: o.SetVtxBoundaryInterpolation(Sdc::Options::VTX_BOUNDARY_NONE); break;
        case SubdivBoundary::edge_only:
            o.SetVtxBoundaryInterpolation(Sdc::Options::VTX_BOUNDARY_EDGE_ONLY);
            break;
        default: o.SetVtxBoundaryInterpolation(Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER);
    }
    Sdc::Options::FVarLinearInterpolation fl = Sdc::Options::FVAR_LINEAR_CORNERS_PLUS1;
    switch (in.fvar_linear) {
        case SubdivFVarLinear::none: fl = Sdc::Options::FVAR_LINEAR_NONE; break;
        case SubdivFVarLinear::corners_only: fl = Sdc::Options::FVAR_LINEAR_CORNERS_ONLY; break;
        case SubdivFVarLinear::corners_plus2: fl = Sdc::Options::FVAR_LINEAR_CORNERS_PLUS2; break;
        case SubdivFVarLinear::boundaries: fl = Sdc::Options::FVAR_LINEAR_BOUNDARIES; break;
        case SubdivFVarLinear::all: fl = Sdc::Options::FVAR_LINEAR_ALL; break;
        default: break;
    }
    o.SetFVarLinearInterpolation(fl);
    o.SetTriangleSubdivision(in.smooth_triangles ? Sdc::Options::TRI_SUB_SMOOTH
                                                 : Sdc::Options::TRI_SUB_CATMARK);
    return o;
}

void validate(const SubdivInput& in) {
    const std::string& n = in.name;
    if (in.points.size() % 3 != 0) CMLT_THROW(SceneError, "subdivide '" << n << "': points must be (N, 3)");
    const size_t n_points = in.points.size() / 3;
    if (in.level < 1 || in.level > 8)
        CMLT_THROW(SceneError, "subdivide '" << n << "': level must be 1..8, got " << in.level);
    size_t corners = 0;
    for (int32_t c : in.face_counts) {
        if (c < 3) CMLT_THROW(SceneError, "subdivide '" << n << "': a face has " << c << " vertices (need >= 3)");
        corners += size_t(c);
    }
    if (corners != in.face_indices.size())
        CMLT_THROW(SceneError, "subdivide '" << n << "': faceVertexCounts sums to " << corners
                                             << " but faceVertexIndices has " << in.face_indices.size());
    auto check_vertex = [&](int32_t v, const char* what) {
        if (v < 0 || size_t(v) >= n_points)
            CMLT_THROW(SceneError, "subdivide '" << n << "': " << what << " refers to point " << v
                                                 << " but points has " << n_points << " entries");
    };
    for (int32_t v : in.face_indices) check_vertex(v, "faceVertexIndices");
    for (int32_t v : in.crease_indices) check_vertex(v, "creaseIndices");
    for (int32_t v : in.corner_indices) check_vertex(v, "cornerIndices");
    for (int32_t f : in.hole_indices)
        if (f < 0 || size_t(f) >= in.face_counts.size())
            CMLT_THROW(SceneError, "subdivide '" << n << "': holeIndices refers to face " << f);
    for (double x : in.points)
        if (!std::isfinite(x)) CMLT_THROW(SceneError, "subdivide '" << n << "': points have NaN or Inf");
    if (in.corner_sharpnesses.size() != in.corner_indices.size() &&
        in.corner_sharpnesses.size() != 1 && !in.corner_indices.empty())
        CMLT_THROW(SceneError, "subdivide '" << n << "': " << in.corner_indices.size() << " cornerIndices but "
                                             << in.corner_sharpnesses.size() << " cornerSharpnesses");
    if (in.vertex_width < 0 || (in.vertex_width > 0 &&
                                in.vertex_data.size() != n_points * size_t(in.vertex_width)))
        CMLT_THROW(SceneError, "subdivide '" << n << "': vertex data must be (N, k) with N = " << n_points);
    for (const SubdivFVarChannel& ch : in.face_varying) {
        if (ch.width < 1 || ch.values.size() % size_t(ch.width) != 0)
            CMLT_THROW(SceneError, "subdivide '" << n << "': a face-varying channel is not (L, k)");
        if (ch.indices.size() != in.face_indices.size())
            CMLT_THROW(SceneError, "subdivide '" << n << "': a face-varying channel has " << ch.indices.size()
                                                 << " indices for " << in.face_indices.size() << " corners");
        const int32_t n_values = int32_t(ch.values.size() / size_t(ch.width));
        for (int32_t i : ch.indices)
            if (i < 0 || i >= n_values)
                CMLT_THROW(SceneError, "subdivide '" << n << "': a face-varying index " << i << " is out of range ("
                                                     << n_values << " values)");
    }
}

/// USD crease chains -> OpenSubdiv crease edges (vertex pairs) with one weight each.
void crease_edges(const SubdivInput& in, std::vector<int>* pairs, std::vector<float>* weights) {
    size_t pos = 0, n_edges_total = 0;
    for (int32_t len : in.crease_lengths) n_edges_total += len > 1 ? size_t(len - 1) : 0;
    const bool per_edge = in.crease_sharpnesses.size() == n_edges_total &&
                          in.crease_sharpnesses.size() != in.crease_lengths.size();
    size_t edge = 0;
    for (size_t c = 0; c < in.crease_lengths.size(); ++c) {
        const int32_t len = in.crease_lengths[c];
        if (len < 0 || pos + size_t(len) > in.crease_indices.size())
            CMLT_THROW(SceneError, "subdivide '" << in.name << "': creaseLengths add up to more than the "
                                                 << in.crease_indices.size() << " creaseIndices");
        for (int32_t k = 0; k + 1 < len; ++k, ++edge) {
            pairs->push_back(in.crease_indices[pos + size_t(k)]);
            pairs->push_back(in.crease_indices[pos + size_t(k) + 1]);
            float w = 0.f;
            if (per_edge) w = in.crease_sharpnesses[edge];
            else if (c < in.crease_sharpnesses.size()) w = in.crease_sharpnesses[c];
            else if (!in.crease_sharpnesses.empty()) w = in.crease_sharpnesses.back();
            weights->push_back(std::isfinite(w) ? std::max(w, 0.f) : 0.f);
        }
        pos += size_t(len);
    }
}

}  // namespace

SubdivResult subdivide(const SubdivInput& in) {
    validate(in);
    const int n_points = int(in.points.size() / 3);

    // ---- topology
    std::vector<int> pairs;
    std::vector<float> crease_w;
    crease_edges(in, &pairs, &crease_w);
    std::vector<float> corner_w(in.corner_indices.size());
    for (size_t i = 0; i < corner_w.size(); ++i) {
        float w = in.corner_sharpnesses.size() == 1 ? in.corner_sharpnesses[0] : in.corner_sharpnesses[i];
        corner_w[i] = std::isfinite(w) ? std::max(w, 0.f) : 0.f;
    }
    std::vector<Far::TopologyDescriptor::FVarChannel> fvar(in.face_varying.size());
    for (size_t c = 0; c < fvar.size(); ++c) {
        fvar[c].numValues = int(in.face_varying[c].values.size() / size_t(in.face_varying[c].width));
        fvar[c].valueIndices = in.face_varying[c].indices.data();
    }
    Far::TopologyDescriptor desc;
    desc.numVertices = n_points;
    desc.numFaces = int(in.face_counts.size());
    desc.numVertsPerFace = in.face_counts.data();
    desc.vertIndicesPerFace = in.face_indices.data();
    desc.numCreases = int(crease_w.size());
    desc.creaseVertexIndexPairs = pairs.data();
    desc.creaseWeights = crease_w.data();
    desc.numCorners = int(in.corner_indices.size());
    desc.cornerVertexIndices = in.corner_indices.data();
    desc.cornerWeights = corner_w.data();
    desc.numHoles = int(in.hole_indices.size());
    desc.holeIndices = in.hole_indices.data();
    desc.numFVarChannels = int(fvar.size());
    desc.fvarChannels = fvar.data();

    using Factory = Far::TopologyRefinerFactory<Far::TopologyDescriptor>;
    Far::SetErrorCallback(osd_error);
    t_osd_error.clear();
    std::unique_ptr<Far::TopologyRefiner> refiner(
        Factory::Create(desc, Factory::Options(scheme_type(in.scheme), sdc_options(in))));
    if (!refiner)
        CMLT_THROW(SceneError, "subdivide '" << in.name << "': OpenSubdiv rejected the topology ("
                                             << (t_osd_error.empty() ? "no reason given" : t_osd_error)
                                             << ")");
    Far::TopologyRefiner::UniformOptions uo(in.level);
    uo.fullTopologyInLastLevel = true;
    refiner->RefineUniform(uo);

    // ---- interpolate level by level (points with the vertex data appended)
    const int w = 3 + in.vertex_width;
    Buffer cur(size_t(n_points), w);
    for (int v = 0; v < n_points; ++v) {
        for (int k = 0; k < 3; ++k) cur.data[size_t(v) * size_t(w) + size_t(k)] = in.points[size_t(v) * 3 + size_t(k)];
        for (int k = 0; k < in.vertex_width; ++k)
            cur.data[size_t(v) * size_t(w) + 3 + size_t(k)] = in.vertex_data[size_t(v) * size_t(in.vertex_width) + size_t(k)];
    }
    std::vector<Buffer> fv;
    for (const SubdivFVarChannel& ch : in.face_varying) {
        fv.emplace_back(ch.values.size() / size_t(ch.width), ch.width);
        fv.back().data = ch.values;
    }
    Far::PrimvarRefiner primvar(*refiner);
    for (int level = 1; level <= in.level; ++level) {
        const Far::TopologyLevel& tl = refiner->GetLevel(level);
        Buffer next(size_t(tl.GetNumVertices()), w);
        primvar.Interpolate(level, cur, next);
        cur = std::move(next);
        for (size_t c = 0; c < fv.size(); ++c) {
            Buffer nf(size_t(tl.GetNumFVarValues(int(c))), fv[c].width);
            primvar.InterpolateFaceVarying(level, fv[c], nf, int(c));
            fv[c] = std::move(nf);
        }
    }

    // ---- limit positions and normals of the last level
    const Far::TopologyLevel& last = refiner->GetLevel(in.level);
    const int n_out = last.GetNumVertices();
    Buffer pos(size_t(n_out), 3), du(size_t(n_out), 3), dv(size_t(n_out), 3);
    Buffer pts(size_t(n_out), 3);
    for (int v = 0; v < n_out; ++v)
        for (int k = 0; k < 3; ++k) pts.data[size_t(v) * 3 + size_t(k)] = cur.data[size_t(v) * size_t(w) + size_t(k)];
    primvar.Limit(pts, pos, du, dv);

    SubdivResult out;
    out.points = pos.data;
    out.normals.assign(size_t(n_out) * 3, 0.0);
    for (int v = 0; v < n_out; ++v) {
        const double* a = &du.data[size_t(v) * 3];
        const double* b = &dv.data[size_t(v) * 3];
        double n[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
        double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (len > 0 && std::isfinite(len))
            for (int k = 0; k < 3; ++k) out.normals[size_t(v) * 3 + size_t(k)] = n[k] / len;
    }
    for (double& x : out.points)
        if (!std::isfinite(x)) CMLT_THROW(SceneError, "subdivide '" << in.name << "': the limit surface is not finite");
    if (in.vertex_width > 0) {
        out.vertex_data.resize(size_t(n_out) * size_t(in.vertex_width));
        for (int v = 0; v < n_out; ++v)
            for (int k = 0; k < in.vertex_width; ++k)
                out.vertex_data[size_t(v) * size_t(in.vertex_width) + size_t(k)] =
                    cur.data[size_t(v) * size_t(w) + 3 + size_t(k)];
    }

    // ---- faces of the last level (holes left out), each with its authored face
    out.face_varying.resize(fv.size());
    for (size_t c = 0; c < fv.size(); ++c) {
        out.face_varying[c].width = fv[c].width;
        out.face_varying[c].values = fv[c].data;
    }
    for (int f = 0; f < last.GetNumFaces(); ++f) {
        if (last.IsFaceHole(f)) continue;
        Far::ConstIndexArray fvs = last.GetFaceVertices(f);
        out.face_counts.push_back(fvs.size());
        for (int k = 0; k < fvs.size(); ++k) out.face_indices.push_back(fvs[k]);
        int p = f;
        for (int level = in.level; level > 0; --level) p = refiner->GetLevel(level).GetFaceParentFace(p);
        out.face_parent.push_back(p);
        for (size_t c = 0; c < fv.size(); ++c) {
            Far::ConstIndexArray vals = last.GetFaceFVarValues(f, int(c));
            for (int k = 0; k < vals.size(); ++k) out.face_varying[c].indices.push_back(vals[k]);
        }
    }
    return out;
}

}  // namespace cmlt
