// Bindings of the geometry helpers: subdivision surfaces (geometry/subdivision.h).
#include "bind_common.h"

#include "geometry/subdivision.h"
#include "util/error.h"

#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

namespace cmlt::bindings {

using namespace nb::literals;

namespace {

using F64 = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;
using I32 = nb::ndarray<const int32_t, nb::c_contig, nb::device::cpu>;
using F32 = nb::ndarray<const float, nb::c_contig, nb::device::cpu>;

template <typename T, typename A>
std::vector<T> to_vector(const A& a) {
    const T* p = a.data();
    return std::vector<T>(p, p + a.size());
}

template <typename T>
nb::ndarray<nb::numpy, T> to_numpy(std::vector<T>&& v, size_t rows, size_t cols) {
    auto* heap = new std::vector<T>(std::move(v));
    nb::capsule owner(heap, [](void* p) noexcept { delete static_cast<std::vector<T>*>(p); });
    if (cols == 0) {
        size_t shape[1] = {rows};
        return nb::ndarray<nb::numpy, T>(heap->data(), 1, shape, owner);
    }
    size_t shape[2] = {rows, cols};
    return nb::ndarray<nb::numpy, T>(heap->data(), 2, shape, owner);
}

SubdivScheme scheme_of(const std::string& s) {
    if (s == "catmullClark") return SubdivScheme::catmull_clark;
    if (s == "loop") return SubdivScheme::loop;
    if (s == "bilinear") return SubdivScheme::bilinear;
    throw nb::value_error(("subdivide: scheme must be catmullClark, loop or bilinear, got '" + s + "'").c_str());
}

SubdivBoundary boundary_of(const std::string& s) {
    if (s == "none") return SubdivBoundary::none;
    if (s == "edgeOnly") return SubdivBoundary::edge_only;
    if (s == "edgeAndCorner") return SubdivBoundary::edge_and_corner;
    throw nb::value_error(("subdivide: interpolate_boundary must be none, edgeOnly or edgeAndCorner, got '" +
                           s + "'").c_str());
}

SubdivFVarLinear fvar_of(const std::string& s) {
    if (s == "none") return SubdivFVarLinear::none;
    if (s == "cornersOnly") return SubdivFVarLinear::corners_only;
    if (s == "cornersPlus1") return SubdivFVarLinear::corners_plus1;
    if (s == "cornersPlus2") return SubdivFVarLinear::corners_plus2;
    if (s == "boundaries") return SubdivFVarLinear::boundaries;
    if (s == "all") return SubdivFVarLinear::all;
    throw nb::value_error(("subdivide: face_varying_linear must be a UsdGeom "
                           "faceVaryingLinearInterpolation token, got '" + s + "'").c_str());
}

nb::dict subdivide_py(F64 points, I32 face_counts, I32 face_indices, const std::string& scheme,
                      int level, I32 crease_indices, I32 crease_lengths, F32 crease_sharpnesses,
                      I32 corner_indices, F32 corner_sharpnesses, I32 hole_indices,
                      const std::string& interpolate_boundary, const std::string& face_varying_linear,
                      bool smooth_triangles, nb::object vertex_data,
                      std::vector<std::tuple<F64, I32>> face_varying, const std::string& name) {
    if (points.ndim() != 2 || points.shape(1) != 3)
        throw nb::value_error("subdivide: points must have shape (N, 3)");
    SubdivInput in;
    in.name = name;
    in.points = to_vector<double>(points);
    in.face_counts = to_vector<int32_t>(face_counts);
    in.face_indices = to_vector<int32_t>(face_indices);
    in.scheme = scheme_of(scheme);
    in.level = level;
    in.crease_indices = to_vector<int32_t>(crease_indices);
    in.crease_lengths = to_vector<int32_t>(crease_lengths);
    in.crease_sharpnesses = to_vector<float>(crease_sharpnesses);
    in.corner_indices = to_vector<int32_t>(corner_indices);
    in.corner_sharpnesses = to_vector<float>(corner_sharpnesses);
    in.hole_indices = to_vector<int32_t>(hole_indices);
    in.boundary = boundary_of(interpolate_boundary);
    in.fvar_linear = fvar_of(face_varying_linear);
    in.smooth_triangles = smooth_triangles;
    if (!vertex_data.is_none()) {
        F64 vd = nb::cast<F64>(vertex_data);
        if (vd.ndim() != 2 || vd.shape(0) != points.shape(0))
            throw nb::value_error("subdivide: vertex_data must have shape (N, k), N = the points");
        in.vertex_width = int(vd.shape(1));
        in.vertex_data = to_vector<double>(vd);
    }
    for (auto& [values, indices] : face_varying) {
        if (values.ndim() != 2) throw nb::value_error("subdivide: face_varying values must be (L, k)");
        SubdivFVarChannel ch;
        ch.width = int(values.shape(1));
        ch.values = to_vector<double>(values);
        ch.indices = to_vector<int32_t>(indices);
        in.face_varying.push_back(std::move(ch));
    }
    SubdivResult r;
    {
        nb::gil_scoped_release release;
        r = subdivide(in);
    }
    const size_t n = r.points.size() / 3;
    nb::dict out;
    out["points"] = to_numpy(std::move(r.points), n, 3);
    out["normals"] = to_numpy(std::move(r.normals), n, 3);
    const size_t n_faces = r.face_counts.size(), n_corners = r.face_indices.size();
    out["face_counts"] = to_numpy(std::move(r.face_counts), n_faces, 0);
    out["face_indices"] = to_numpy(std::move(r.face_indices), n_corners, 0);
    out["face_parent"] = to_numpy(std::move(r.face_parent), n_faces, 0);
    if (in.vertex_width > 0)
        out["vertex_data"] = to_numpy(std::move(r.vertex_data), n, size_t(in.vertex_width));
    nb::list fv;
    for (SubdivFVarChannel& ch : r.face_varying) {
        const size_t rows = ch.values.size() / size_t(ch.width), ni = ch.indices.size();
        fv.append(nb::make_tuple(to_numpy(std::move(ch.values), rows, size_t(ch.width)),
                                 to_numpy(std::move(ch.indices), ni, 0)));
    }
    out["face_varying"] = fv;
    return out;
}

}  // namespace

void bind_geometry(nb::module_& m) {
    m.def("subdivide", &subdivide_py, "points"_a, "face_counts"_a, "face_indices"_a,
          "scheme"_a = "catmullClark", "level"_a = 2, "crease_indices"_a, "crease_lengths"_a,
          "crease_sharpnesses"_a, "corner_indices"_a, "corner_sharpnesses"_a, "hole_indices"_a,
          "interpolate_boundary"_a = "edgeAndCorner", "face_varying_linear"_a = "cornersPlus1",
          "smooth_triangles"_a = false, "vertex_data"_a = nb::none(),
          "face_varying"_a = std::vector<std::tuple<F64, I32>>(), "name"_a = "mesh",
          "Refine a subdivision surface (OpenSubdiv, uniform, `level` 1..8) as UsdGeom.Mesh\n"
          "describes it: points float64 (N,3), face_counts / face_indices int32, USD creases\n"
          "(creaseIndices, creaseLengths, creaseSharpnesses per crease or per edge), corners,\n"
          "holes, interpolateBoundary, faceVaryingLinearInterpolation, triangleSubdivisionRule\n"
          "smooth; vertex_data (N,k) float64 refined like the points; face_varying: a list of\n"
          "(values (L,k) float64, indices int32 per corner). Returns a dict: points and normals\n"
          "(n,3) on the limit surface, face_counts, face_indices, face_parent (the authored face\n"
          "of each refined face), vertex_data, face_varying [(values, indices)]. Raises\n"
          "SceneError naming `name` on bad topology.");
}

}  // namespace cmlt::bindings
