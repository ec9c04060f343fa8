#pragma once
/// \file Subdivision surfaces refined with OpenSubdiv (Far): a UsdGeom.Mesh control cage
/// (catmullClark, loop or bilinear, with creases, corners, holes and the boundary rules)
/// refined uniformly to a level, its vertices projected onto the limit surface with limit
/// normals, and its primvars carried along (vertex data like the points, face-varying data
/// per refined face corner, uniform data through each refined face's authored face).
///
/// OpenSubdiv is private to geometry/subdivision.cpp; nothing else includes it.
#include <cstdint>
#include <string>
#include <vector>

namespace cmlt {

enum class SubdivScheme { catmull_clark, loop, bilinear };
/// UsdGeom interpolateBoundary.
enum class SubdivBoundary { none, edge_only, edge_and_corner };
/// UsdGeom faceVaryingLinearInterpolation.
enum class SubdivFVarLinear { none, corners_only, corners_plus1, corners_plus2, boundaries, all };

/// A face-varying channel: `values` (n_values x width) and one value index per face corner.
struct SubdivFVarChannel {
    std::vector<double> values;
    int width = 0;
    std::vector<int32_t> indices;
};

struct SubdivInput {
    std::vector<double> points;            ///< (n_points x 3)
    std::vector<int32_t> face_counts;      ///< per face
    std::vector<int32_t> face_indices;     ///< per face corner
    SubdivScheme scheme = SubdivScheme::catmull_clark;
    SubdivBoundary boundary = SubdivBoundary::edge_and_corner;
    SubdivFVarLinear fvar_linear = SubdivFVarLinear::corners_plus1;
    bool smooth_triangles = false;         ///< triangleSubdivisionRule = smooth
    /// USD creases: chains of vertices (creaseIndices / creaseLengths), sharpness per chain
    /// or per edge (creaseSharpnesses); 10 = infinitely sharp.
    std::vector<int32_t> crease_indices, crease_lengths;
    std::vector<float> crease_sharpnesses;
    std::vector<int32_t> corner_indices;
    std::vector<float> corner_sharpnesses;
    std::vector<int32_t> hole_indices;
    /// Extra per-vertex data refined like the points (vertex / varying primvars).
    std::vector<double> vertex_data;
    int vertex_width = 0;
    std::vector<SubdivFVarChannel> face_varying;
    int level = 2;                         ///< uniform refinement level, 1..8
    std::string name = "mesh";             ///< for error messages
};

struct SubdivResult {
    std::vector<double> points;            ///< (n x 3) on the limit surface
    std::vector<double> normals;           ///< (n x 3) unit limit normals (0 where undefined)
    std::vector<int32_t> face_counts;      ///< refined faces (holes left out)
    std::vector<int32_t> face_indices;
    std::vector<int32_t> face_parent;      ///< authored face of each refined face
    std::vector<double> vertex_data;       ///< (n x vertex_width)
    std::vector<SubdivFVarChannel> face_varying;  ///< per channel, indices per refined corner
};

/// Refine `in`. Throws SceneError naming `in.name` on bad topology or arguments.
SubdivResult subdivide(const SubdivInput& in);

}  // namespace cmlt
