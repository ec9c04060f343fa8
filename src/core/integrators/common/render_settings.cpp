#include "integrators/common/render_settings.h"

#include "film/filter.h"
#include "util/error.h"

#include <cmath>
#include <sstream>

namespace cmlt {

namespace {

/// Whether `value` is one of the space-separated tokens of `allowed`.
bool is_token(const std::string& value, const char* allowed) {
    std::istringstream in(allowed);
    std::string t;
    while (in >> t)
        if (t == value) return true;
    return false;
}

/// "'a', 'b', 'c'" from "a b c".
std::string quoted_tokens(const char* allowed) {
    std::istringstream in(allowed);
    std::ostringstream out;
    std::string t;
    for (bool first = true; in >> t; first = false) out << (first ? "" : ", ") << "'" << t << "'";
    return out.str();
}

}  // namespace

void RenderSettings::validate() const {
#define CMLT_CHECK_INT(name, def, lo, hi, attr, flag, doc)                                    \
    if (name < (lo) || name > (hi))                                                           \
        CMLT_THROW(SettingsError, "RenderSettings." #name ": must be in [" << (lo) << ", "    \
                                                                          << (hi) << "], got " \
                                                                          << name);
#define CMLT_CHECK_REAL(name, def, lo, hi, lo_open, attr, flag, doc)                           \
    if (!std::isfinite(name) || ((lo_open) ? !(name > (lo)) : !(name >= (lo))) ||             \
        !(name <= (hi)))                                                                      \
        CMLT_THROW(SettingsError, "RenderSettings." #name ": must be finite and in "          \
                                      << ((lo_open) ? "(" : "[") << (lo) << ", " << (hi)      \
                                      << "], got " << name);
#define CMLT_CHECK_NOTHING(name, def, attr, flag, doc)
#define CMLT_CHECK_TOKEN(name, def, allowed, attr, flag, doc)                                 \
    if (!is_token(name, allowed))                                                             \
        CMLT_THROW(SettingsError, "RenderSettings." #name ": unknown value '"                 \
                                      << name << "' (available: " << quoted_tokens(allowed)   \
                                      << ")");
    CMLT_RENDER_SETTINGS(CMLT_CHECK_INT, CMLT_CHECK_REAL, CMLT_CHECK_NOTHING, CMLT_CHECK_NOTHING,
                         CMLT_CHECK_TOKEN)
#undef CMLT_CHECK_INT
#undef CMLT_CHECK_REAL
#undef CMLT_CHECK_NOTHING
#undef CMLT_CHECK_TOKEN
    if (mlt_paths == "caustics" && direct_fraction == 0.0)
        CMLT_THROW(SettingsError, "RenderSettings.direct_fraction: must be > 0 with mlt_paths '"
                                      << mlt_paths << "' (the direct pass renders every path the chains leave)");
    if (error_groups == 1 || error_groups == 2)
        CMLT_THROW(SettingsError, "RenderSettings.error_groups: 0 (off) or 3..64, got " << error_groups
                                      << " (a variance and its jackknife need 3 groups)");
    if (filter_radius != 0.0) PixelFilter::from_settings(pixel_filter, filter_radius);  // its range
    // across fields: at most 2^31 pixels
    if (int64_t(width) * int64_t(height) > (int64_t(1) << 31))
        CMLT_THROW(SettingsError, "RenderSettings.width: width * height is too large ("
                                      << width << " x " << height << ")");
    if (!(film_offset_x >= 0.0 && film_offset_x < 1.0 && film_offset_y >= 0.0 &&
          film_offset_y < 1.0))
        CMLT_THROW(SettingsError, "RenderSettings.film_offset must be in [0, 1) per axis, got "
                                      << film_offset_x << ", " << film_offset_y);
    if (pixel_keys) {
        const uint64_t n = uint64_t(width) * uint64_t(height);
        if (pixel_keys->size() != n)
            CMLT_THROW(SettingsError, "RenderSettings.pixel_keys: " << pixel_keys->size()
                                          << " keys for " << width << " x " << height << " pixels");
        std::vector<bool> seen(n, false);
        for (uint32_t k : *pixel_keys) {
            if (k >= n || seen[k])
                CMLT_THROW(SettingsError, "RenderSettings.pixel_keys: not a permutation of 0.." << n - 1 << " (key "
                                              << k << (k >= n ? " out of range)" : " twice)"));
            seen[k] = true;
        }
    }
    if (partial && !(part_row_begin >= 0 && part_row_begin <= part_row_end && part_row_end <= height &&
                     part_chain_begin <= part_chain_end))
        CMLT_THROW(SettingsError, "RenderSettings.part_*: rows [" << part_row_begin << ", " << part_row_end
                                      << ") must lie in [0, height = " << height << "] and chains ["
                                      << part_chain_begin << ", " << part_chain_end << ") be a range");
}

}  // namespace cmlt
