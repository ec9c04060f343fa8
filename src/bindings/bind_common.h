#pragma once
/// \file Helpers shared by the binding files: argument checks before calling the core.
///
/// Array arguments are taken as generic read-only ndarrays and checked here, so that
/// errors name the argument (TypeError for dtype, ValueError for shape/layout), as
/// cholespy does, instead of nanobind's generic overload-resolution message.
#include "math/mat4.h"

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <memory>
#include <string>
#include <vector>

namespace cmlt::bindings {

namespace nb = nanobind;
using AnyArray = nb::ndarray<nb::ro, nb::device::cpu>;

std::string dtype_name(const nb::dlpack::dtype& dt);

/// Convert `obj` to an array or raise TypeError naming `fn` and `arg`.
AnyArray as_array(nb::handle obj, const char* fn, const char* arg);

/// Check dtype T, ndim 2 (or 1 if cols == 0), shape (rows?, cols), C-contiguous.
/// rows < 0: any. Raises TypeError / ValueError naming the argument.
template <typename T>
const T* checked_matrix(const AnyArray& a, const char* fn, const char* arg, long rows, long cols,
                        const char* dtype_str);

/// float64 or float32 (4, 4), any strides -> Mat4 (column-vector convention).
Mat4 to_mat4(nb::handle obj, const char* fn, const char* arg);

/// Keep Python objects alive from C++; releases them with the GIL held.
std::shared_ptr<void> make_owner(std::vector<nb::object> objs);

/// float32 (h, w, 3) numpy array owning `v` (an RGB image, row by row).
nb::object rgb_to_numpy(std::vector<float>&& v, int h, int w);

void bind_scene(nb::module_& m);
void bind_settings(nb::module_& m);  ///< RenderSettings: before bind_render
void bind_render(nb::module_& m);
void bind_temporal(nb::module_& m);
void bind_geometry(nb::module_& m);

}  // namespace cmlt::bindings
