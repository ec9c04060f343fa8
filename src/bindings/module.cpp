// cmlt._core: the nanobind module (see bind_scene.cpp, bind_render.cpp).
#include "bind_common.h"

#include "accel/accel.h"
#include "util/error.h"

#include <sstream>

namespace cmlt::bindings {

std::string dtype_name(const nb::dlpack::dtype& dt) {
    std::ostringstream os;
    switch (nb::dlpack::dtype_code(dt.code)) {
        case nb::dlpack::dtype_code::Int: os << "int"; break;
        case nb::dlpack::dtype_code::UInt: os << "uint"; break;
        case nb::dlpack::dtype_code::Float: os << "float"; break;
        case nb::dlpack::dtype_code::Bool: os << "bool"; break;
        default: os << "dtype" << int(dt.code); break;
    }
    os << int(dt.bits);
    return os.str();
}

AnyArray as_array(nb::handle obj, const char* fn, const char* arg) {
    AnyArray a;
    if (!nb::try_cast(obj, a, false)) {
        std::string tn = nb::type_name(obj.type()).c_str();
        throw nb::type_error((std::string(fn) + ": " + arg +
                              " must be a numpy array (C-contiguous, on the CPU), got " + tn)
                                 .c_str());
    }
    return a;
}

template <typename T>
const T* checked_matrix(const AnyArray& a, const char* fn, const char* arg, long rows, long cols,
                        const char* dtype_str) {
    std::string where = std::string(fn) + ": " + arg;
    if (a.dtype() != nb::dtype<T>())
        throw nb::type_error((where + " must have dtype " + dtype_str + ", got " +
                              dtype_name(a.dtype()) + " (convert with np.ascontiguousarray(x, np." +
                              dtype_str + "))")
                                 .c_str());
    size_t want_ndim = cols > 0 ? 2 : 1;
    auto shape_str = [&] {
        std::ostringstream os;
        os << "(";
        for (size_t i = 0; i < a.ndim(); ++i) os << (i ? ", " : "") << a.shape(i);
        os << (a.ndim() == 1 ? ",)" : ")");
        return os.str();
    };
    if (a.ndim() != want_ndim || (cols > 0 && long(a.shape(1)) != cols) ||
        (rows >= 0 && long(a.shape(0)) != rows)) {
        std::ostringstream os;
        os << where << " must have shape (" << (rows >= 0 ? std::to_string(rows) : std::string("N"));
        if (cols > 0) os << ", " << cols << ")";
        else os << ",)";
        os << ", got " << shape_str();
        throw nb::value_error(os.str().c_str());
    }
    bool contiguous = (cols <= 0 || a.shape(0) <= 1 || a.stride(0) == cols) &&
                      (cols <= 0 ? (a.shape(0) <= 1 || a.stride(0) == 1) : a.stride(1) == 1);
    if (!contiguous)
        throw nb::value_error((where + " must be C-contiguous (use np.ascontiguousarray)").c_str());
    return static_cast<const T*>(a.data());
}

template const float* checked_matrix<float>(const AnyArray&, const char*, const char*, long, long,
                                            const char*);
template const uint32_t* checked_matrix<uint32_t>(const AnyArray&, const char*, const char*, long,
                                                  long, const char*);

Mat4 to_mat4(nb::handle obj, const char* fn, const char* arg) {
    AnyArray a = as_array(obj, fn, arg);
    std::string where = std::string(fn) + ": " + arg;
    bool f64 = a.dtype() == nb::dtype<double>(), f32 = a.dtype() == nb::dtype<float>();
    if (!f64 && !f32)
        throw nb::type_error((where + " must be a float64 (4, 4) matrix, got dtype " +
                              dtype_name(a.dtype()))
                                 .c_str());
    if (a.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4)
        throw nb::value_error((where + " must have shape (4, 4)").c_str());
    Mat4 m;
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) {
            int64_t off = r * a.stride(0) + c * a.stride(1);
            m.m[r][c] = f64 ? static_cast<const double*>(a.data())[off]
                            : double(static_cast<const float*>(a.data())[off]);
        }
    return m;
}

std::shared_ptr<void> make_owner(std::vector<nb::object> objs) {
    auto* p = new std::vector<nb::object>(std::move(objs));
    return std::shared_ptr<void>(p, [](void* q) {
        auto* v = static_cast<std::vector<nb::object>*>(q);
        if (!Py_IsInitialized()) return;  // interpreter gone: leak rather than crash
        nb::gil_scoped_acquire gil;
        delete v;
    });
}

}  // namespace cmlt::bindings

NB_MODULE(_core, m) {
    namespace nb = nanobind;
    using namespace cmlt::bindings;
    m.doc() = "cmlt C++ core: scene, Embree BVH, integrators (pt, bdpt, pssmlt, cmlt), temporal carry-over";
    m.attr("__version__") = CMLT_VERSION;  // pyproject.toml's version (CMakeLists.txt)
    // the x86-64 level this build of the module was compiled for (src/bindings/CMakeLists.txt)
    m.attr("isa") = CMLT_CORE_ISA;
    nb::exception<cmlt::SceneError>(m, "SceneError", PyExc_ValueError);
    nb::exception<cmlt::SettingsError>(m, "SettingsError", PyExc_ValueError);
    m.def("max_packet_width", &cmlt::Accel::max_packet_width,
          "Largest ray-packet width (4, 8 or 16) this Embree build supports natively on this CPU.");
    bind_scene(m);
    bind_render(m);
    bind_temporal(m);
    bind_geometry(m);
    bind_analysis(m);
}
