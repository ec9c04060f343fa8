#pragma once
/// \file Typed exceptions and always-on checks (STYLE.md §5).
///
/// SceneError: bad scene input (arrays, indices, NaN points, Embree failures).
/// SettingsError: bad render settings; the message names the field.
/// CMLT_CHECK stays on in release builds; CMLT_DCHECK only in debug builds.
#include <sstream>
#include <stdexcept>
#include <string>

namespace cmlt {

class SceneError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

class SettingsError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

namespace detail {
[[noreturn]] inline void check_failed(const char* expr, const char* file, int line,
                                      const std::string& msg) {
    std::ostringstream os;
    os << "cmlt internal check failed: " << expr << " at " << file << ":" << line;
    if (!msg.empty()) os << ": " << msg;
    throw std::logic_error(os.str());
}
}  // namespace detail

}  // namespace cmlt

#define CMLT_CHECK(expr)                                                            \
    do {                                                                            \
        if (!(expr)) ::cmlt::detail::check_failed(#expr, __FILE__, __LINE__, ""); \
    } while (0)

#define CMLT_CHECK_MSG(expr, msg)                                                       \
    do {                                                                                \
        if (!(expr)) {                                                                  \
            std::ostringstream cmlt_os_;                                                \
            cmlt_os_ << msg;                                                            \
            ::cmlt::detail::check_failed(#expr, __FILE__, __LINE__, cmlt_os_.str());    \
        }                                                                               \
    } while (0)

#ifndef NDEBUG
#define CMLT_DCHECK(expr) CMLT_CHECK(expr)
#else
#define CMLT_DCHECK(expr) \
    do {                  \
    } while (0)
#endif

/// Throw an exception of type `type` with a streamed message.
#define CMLT_THROW(type, msg)         \
    do {                              \
        std::ostringstream cmlt_os_;  \
        cmlt_os_ << msg;              \
        throw type(cmlt_os_.str());   \
    } while (0)
