// Bindings of RenderSettings, generated from the settings table
// (integrators/common/render_settings.h): one property per field with the table's doc,
// range and default, and settings_table() for the Python side (flags, stage values,
// schema files).
#include "bind_common.h"

#include "integrators/common/render_settings.h"
#include "integrators/mlt/chain_state.h"

#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <cmath>
#include <deque>
#include <limits>
#include <sstream>

namespace cmlt::bindings {

using namespace nb::literals;

namespace {

// -- the settings table (integrators/common/render_settings.h) ----------------------------

/// The table's numeric bounds as Python numbers (None: unbounded).
nb::object bound(double v) { return std::isinf(v) ? nb::none() : nb::object(nb::float_(v)); }
nb::object bound(int v) { return nb::int_(v); }

/// "a b c" -> ('a', 'b', 'c')
nb::tuple token_tuple(const char* allowed) {
    nb::list out;
    std::istringstream in(allowed);
    for (std::string t; in >> t;) out.append(nb::str(t.c_str()));
    return nb::tuple(out);
}

/// "a, b, c" from "a b c"
std::string join_tokens(const char* allowed) {
    std::istringstream in(allowed);
    std::string out, t;
    while (in >> t) out += (out.empty() ? "" : ", ") + t;
    return out;
}

nb::object text_or_none(const char* s) { return *s ? nb::object(nb::str(s)) : nb::none(); }

nb::dict setting_row(const char* name, const char* kind, nb::object def, nb::object lo,
                     nb::object hi, bool lo_open, nb::tuple tokens, const char* attr,
                     const char* flag, const char* doc, bool core) {
    nb::dict d;
    d["name"] = name;
    d["kind"] = kind;  // the USD value type of the schema attribute
    d["default"] = def;
    d["min"] = lo;
    d["max"] = hi;
    d["min_open"] = lo_open;
    d["tokens"] = tokens;
    d["attribute"] = text_or_none(attr);
    d["flag"] = text_or_none(flag);
    d["doc"] = doc;
    d["core"] = core;
    return d;
}

/// Every row of the table, in order: RenderSettings' fields (core = True), then the
/// sequence settings of the Python frame loop (core = False).
nb::list settings_table() {
    nb::list rows;
    bool core = true;
#define CMLT_ROW_INT(name, def, lo, hi, attr, flag, doc)                                     \
    rows.append(setting_row(#name, "int", nb::int_(def), bound(lo), bound(hi), false,        \
                            nb::tuple(), attr, flag, doc, core));
#define CMLT_ROW_REAL(name, def, lo, hi, lo_open, attr, flag, doc)                           \
    rows.append(setting_row(#name, "double", nb::float_(def), bound(lo), bound(hi), lo_open, \
                            nb::tuple(), attr, flag, doc, core));
#define CMLT_ROW_U64(name, def, attr, flag, doc)                                             \
    rows.append(setting_row(#name, "uint64", nb::int_(uint64_t(def)), nb::int_(0),           \
                            nb::int_(std::numeric_limits<uint64_t>::max()), false,           \
                            nb::tuple(), attr, flag, doc, core));
#define CMLT_ROW_BOOL(name, def, attr, flag, doc)                                            \
    rows.append(setting_row(#name, "bool", nb::bool_(def), nb::none(), nb::none(), false,    \
                            nb::tuple(), attr, flag, doc, core));
#define CMLT_ROW_TOKEN(name, def, allowed, attr, flag, doc)                                  \
    rows.append(setting_row(#name, "token", nb::str(def), nb::none(), nb::none(), false,     \
                            token_tuple(allowed), attr, flag, doc, core));
    CMLT_RENDER_SETTINGS(CMLT_ROW_INT, CMLT_ROW_REAL, CMLT_ROW_U64, CMLT_ROW_BOOL, CMLT_ROW_TOKEN)
    core = false;
    CMLT_SEQUENCE_SETTINGS(CMLT_ROW_INT, CMLT_ROW_REAL, CMLT_ROW_U64, CMLT_ROW_BOOL,
                           CMLT_ROW_TOKEN)
#undef CMLT_ROW_INT
#undef CMLT_ROW_REAL
#undef CMLT_ROW_U64
#undef CMLT_ROW_BOOL
#undef CMLT_ROW_TOKEN
    return rows;
}

/// The docstring of a RenderSettings property: the table's doc, range and default.
const char* field_doc(std::string text) {
    static std::deque<std::string> docs;  // nanobind keeps the pointer
    docs.push_back(std::move(text));
    return docs.back().c_str();
}

std::string range_text(int lo, int hi) {
    std::ostringstream os;
    if (hi == settings_limits::k_int_max) os << ">= " << lo;
    else os << lo << ".." << hi;
    return os.str();
}

std::string range_text(double lo, double hi, bool lo_open) {
    std::ostringstream os;
    if (std::isinf(hi)) os << (lo_open ? "> " : ">= ") << lo;
    else os << (lo_open ? "(" : "[") << lo << ", " << hi << "]";
    return os.str();
}

std::string show(bool v) { return v ? "True" : "False"; }
std::string show(int v) { return std::to_string(v); }
std::string show(uint64_t v) { return std::to_string(v); }
std::string show(double v) {
    std::ostringstream os;
    os << v;
    return os.str();
}
std::string show(const std::string& v) { return "'" + v + "'"; }

}  // namespace

void bind_settings(nb::module_& m) {
    auto cls = nb::class_<RenderSettings>(
        m, "RenderSettings",
        "Settings of one frame (validated by render). Fields, defaults and ranges: the "
        "settings table (settings_table(), integrators/common/render_settings.h).");
    cls.def(nb::init<>());
#define CMLT_BIND_INT(name, def, lo, hi, attr, flag, doc)                                    \
    cls.def_rw(#name, &RenderSettings::name,                                                 \
               field_doc(std::string(doc) + "; " + range_text(lo, hi) + " (default " #def ")"));
#define CMLT_BIND_REAL(name, def, lo, hi, lo_open, attr, flag, doc)                          \
    cls.def_rw(#name, &RenderSettings::name,                                                 \
               field_doc(std::string(doc) + "; " + range_text(lo, hi, lo_open) +            \
                         " (default " + show(double(def)) + ")"));
#define CMLT_BIND_U64(name, def, attr, flag, doc)                                            \
    cls.def_rw(#name, &RenderSettings::name,                                                 \
               field_doc(std::string(doc) + "; 0..2^64-1 (default " #def ")"));
#define CMLT_BIND_BOOL(name, def, attr, flag, doc)                                           \
    cls.def_rw(#name, &RenderSettings::name,                                                 \
               field_doc(std::string(doc) + " (default " + show(bool(def)) + ")"));
#define CMLT_BIND_TOKEN(name, def, allowed, attr, flag, doc)                                 \
    cls.def_rw(#name, &RenderSettings::name,                                                 \
               field_doc(std::string(doc) + "; one of " +                                    \
                         join_tokens(allowed) + " (default '" def "')"));
    CMLT_RENDER_SETTINGS(CMLT_BIND_INT, CMLT_BIND_REAL, CMLT_BIND_U64, CMLT_BIND_BOOL,
                         CMLT_BIND_TOKEN)
#undef CMLT_BIND_INT
#undef CMLT_BIND_REAL
#undef CMLT_BIND_U64
#undef CMLT_BIND_BOOL
#undef CMLT_BIND_TOKEN
    cls.def_prop_rw(
        "mlt_initial_states",
        [](const RenderSettings& s) {
            return std::const_pointer_cast<mlt::ChainStates>(s.mlt_initial_states);
        },
        [](RenderSettings& s, std::shared_ptr<mlt::ChainStates> v) { s.mlt_initial_states = std::move(v); },
        nb::arg("value").none(),
        "pssmlt/cmlt: MltStates to start the chains from (one chain per state) instead of "
        "resampling the bootstrap; None (default) = bootstrap");
    cls.def_prop_rw(
        "mlt_bootstrap_f",
        [](const RenderSettings& s) -> nb::object {
            if (!s.mlt_bootstrap_f) return nb::none();
            return nb::cast(*s.mlt_bootstrap_f);
        },
        [](RenderSettings& s, nb::object v) {
            if (v.is_none()) {
                s.mlt_bootstrap_f.reset();
                return;
            }
            s.mlt_bootstrap_f = std::make_shared<const std::vector<double>>(nb::cast<std::vector<double>>(v));
        },
        nb::arg("value").none(),
        "pssmlt/cmlt: f* of the frame's bootstrap samples (list of float, exactly the "
        "frame's bootstrap count) to use instead of evaluating them; None (default) = "
        "evaluate");
    cls.def_rw("film_offset_x", &RenderSettings::film_offset_x,
               "the frame's film offset on the torus, [0, 1): the chains' film position and, "
               "rounded to pixels, the pixel passes' sample keys move with it, unless "
               "pixel_keys is given (a reparametrisation: the same image in expectation; "
               "default 0)");
    cls.def_rw("film_offset_y", &RenderSettings::film_offset_y, "as film_offset_x");
    cls.def_prop_rw(
        "pixel_keys",
        [](const RenderSettings& s) -> nb::object {
            if (!s.pixel_keys) return nb::none();
            return nb::cast(*s.pixel_keys);
        },
        [](RenderSettings& s, nb::object v) {
            if (v.is_none()) {
                s.pixel_keys.reset();
                return;
            }
            nb::ndarray<const uint32_t, nb::ndim<1>, nb::c_contig, nb::device::cpu> a;
            if (nb::try_cast(v, a))  // a uint32 array: copied as is
                s.pixel_keys = std::make_shared<const std::vector<uint32_t>>(a.data(), a.data() + a.size());
            else
                s.pixel_keys = std::make_shared<const std::vector<uint32_t>>(nb::cast<std::vector<uint32_t>>(v));
        },
        nb::arg("value").none(),
        "the sample key of each image pixel (W*H ints, row-major, a permutation of "
        "0..W*H-1) replacing the film offset for the pixel passes' keys and the chains' "
        "film position, so each pixel's numbers and states follow its own screen motion "
        "(the temporal driver's key map); None (default): the film offset");
    cls.def_prop_rw(
        "pilot",
        [](const RenderSettings& s) -> nb::object {
            if (!s.pilot) return nb::none();
            std::vector<float> copy(*s.pilot);
            return rgb_to_numpy(std::move(copy), s.height, s.width);
        },
        [](RenderSettings& s, nb::object v) {
            if (v.is_none()) {
                s.pilot.reset();
                return;
            }
            auto a = nb::cast<nb::ndarray<const float, nb::c_contig, nb::device::cpu>>(v);
            if (a.ndim() != 3 || a.shape(2) != 3)
                throw std::invalid_argument("RenderSettings.pilot: expected a float32 (H, W, 3) array");
            s.pilot = std::make_shared<const std::vector<float>>(a.data(), a.data() + a.size());
        },
        nb::arg("value").none(),
        "the pilot image (float32 (H, W, 3)) of the 'pixel' importance to use instead of "
        "rendering one; None (default) = render it");
    cls.def_rw("partial", &RenderSettings::partial,
               "render one part of the frame (cmlt.shot.distributed): pt the rows part_row_begin.."
               "part_row_end, pssmlt/cmlt the chains part_chain_begin..part_chain_end (and their "
               "direct pass on those rows) with RenderResult.mlt_part the raw sums "
               "(combine_mlt_parts); default False");
    cls.def_rw("part_row_begin", &RenderSettings::part_row_begin, "first row of the part");
    cls.def_rw("part_row_end", &RenderSettings::part_row_end, "row after the part's last");
    cls.def_rw("part_chain_begin", &RenderSettings::part_chain_begin, "first chain of the part");
    cls.def_rw("part_chain_end", &RenderSettings::part_chain_end, "chain after the part's last");
    cls.def("validate", &RenderSettings::validate,
            "Check every field against the settings table (render does it too); raises "
            "SettingsError naming the field.");
    cls.def("__repr__", [](const RenderSettings& s) {
        std::string out = "RenderSettings(";
        const char* sep = "";
#define CMLT_REPR(name, ...)                            \
    out += sep + std::string(#name "=") + show(s.name); \
    sep = ", ";
        CMLT_RENDER_SETTINGS(CMLT_REPR, CMLT_REPR, CMLT_REPR, CMLT_REPR, CMLT_REPR)
#undef CMLT_REPR
        return out + ")";
    });
    m.def("settings_table", &settings_table,
          "The settings table (integrators/common/render_settings.h), one dict per setting: "
          "name, kind (the USD value type: int, double, uint64, bool, token), default, min, "
          "max (None: unbounded), min_open, tokens, attribute (the CmltRenderSettingsAPI "
          "attribute or None), flag ('--name[|--alias] [METAVAR]' or None; a bool's flag sets "
          "the opposite of its default), doc, core (a RenderSettings field; False: a "
          "sequence setting of the Python frame loop).");
}

}  // namespace cmlt::bindings
