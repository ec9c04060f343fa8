#pragma once
/// \file Splat film of the Metropolis integrators (pssmlt, cmlt: integrators/mlt's frame
/// owns one): per-pixel sums of weighted colours, accumulated in 128-bit fixed point (32
/// fractional bits) with atomic integer adds.
///
/// Why fixed point: integer addition is exact and commutative, so the sum does not
/// depend on the order in which chains running on different threads splat — the image
/// is bit-identical for any thread count, with one shared buffer (per-chain double
/// films would cost chains × image memory; per-thread ones depend on the scheduling).
/// The resolution, 2^-32 ≈ 2.3e-10 per splat, is finer than a double's relative
/// precision at the sums reached (the DESIGN.md §2 concern: float sums drift at high
/// sample counts). A single splat beyond ±2^30 is clamped and counted.
///
/// Range: one int64 word would hold ±2^31 per pixel and channel, which a bright pixel
/// passes at high mutation counts (10^6 under the pixel importance at 4,000 mutations per
/// pixel; the luminance target's L/Y of a saturated colour over 10^8 splats) — and wrap
/// around silently. So each sum is a 128-bit two's-complement integer in two words:
/// `lo` (unsigned, the fixed-point value mod 2^64) gets every splat q with fetch_add, and
/// the carry out of that add (known exactly from the value fetch_add returns) plus q's
/// sign extension go to `hi`. Each carry belongs to one add in lo's modification order,
/// so the pair sums exactly whatever the order; hi is touched only when lo wraps (a sum
/// crossing a multiple of 2^32 in value units or changing sign), so the common path is one
/// atomic add as before, and sums inside the old range read back bit-identically.
#include "film/filter.h"
#include "math/vec.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

namespace cmlt {

class SplatFilm {
public:
    static constexpr double k_scale = 4294967296.0;  ///< 2^32: one unit of the sum
    static constexpr double k_max_splat = 1073741824.0;  ///< 2^30

    /// `layers` >= 1 separate sums (the error groups: a chain splats into its group's
    /// layer); sum() adds them up exactly, so the image does not depend on the count.
    SplatFilm(int width, int height, int layers = 1)
        : m_width(width), m_height(height), m_layers(std::max(layers, 1)),
          m_lo(new std::atomic<uint64_t>[size_t(width) * height * 3 * size_t(std::max(layers, 1))]),
          m_hi(new std::atomic<int64_t>[size_t(width) * height * 3 * size_t(std::max(layers, 1))]) {
        for (size_t i = 0, n = size_t(width) * height * 3 * size_t(m_layers); i < n; ++i) {
            m_lo[i].store(0, std::memory_order_relaxed);
            m_hi[i].store(0, std::memory_order_relaxed);
        }
    }

    int width() const { return m_width; }
    int height() const { return m_height; }
    int layers() const { return m_layers; }

    /// Add `weight · colour` to pixel `pixel` (= y·W + x). Thread-safe; order-independent.
    void add(uint32_t pixel, const Spectrum& colour, double weight, int layer = 0) {
        const float c[3] = {colour.x, colour.y, colour.z};
        for (int k = 0; k < 3; ++k) {
            const int64_t q = quantize(double(c[k]) * weight);
            if (q != 0) add_sum(word_index(layer, pixel, k), q);
        }
    }

    /// One channel's splat value v in units of the sum: 0 for NaN (which never reaches
    /// the film: callers check), beyond ±2^30 clamped there and counted.
    int64_t quantize(double v) {
        if (!(v == v)) return 0;
        if (std::fabs(v) > k_max_splat) {
            v = v > 0 ? k_max_splat : -k_max_splat;
            m_clamped.fetch_add(1, std::memory_order_relaxed);
        }
        return round_half_away(v * k_scale);
    }
    /// The word of pixel `pixel`, channel k in `layer`.
    size_t word_index(int layer, uint32_t pixel, int k) const {
        return (size_t(layer) * size_t(m_width) * size_t(m_height) + pixel) * 3 + size_t(k);
    }
    /// Add a 128-bit sum of quantised splats to word i (thread-safe, exact): its low
    /// word to lo, and to hi its high word plus the carry out of lo (known exactly from
    /// the value fetch_add returns); hi is touched only when that is not 0.
    void add_sum(size_t i, __int128 v) {
        const uint64_t lo = uint64_t((unsigned __int128)v);
        const int64_t hi = int64_t(uint64_t((unsigned __int128)v >> 64));
        const uint64_t old = m_lo[i].fetch_add(lo, std::memory_order_relaxed);
        const int64_t dh = hi + int64_t(old + lo < old);
        if (dh != 0) m_hi[i].fetch_add(dh, std::memory_order_relaxed);
    }

    /// Sum of pixel i, channel k over every layer, as a double.
    double sum(size_t i, int k) const {
        __int128 v = 0;
        for (int l = 0; l < m_layers; ++l) v += word(l, i, k);  // exact: wraps as the one sum would
        return double(v) / k_scale;  // rounds once, as the one-word conversion did
    }
    /// Sum of pixel i, channel k in one layer.
    double layer_sum(int layer, size_t i, int k) const { return double(word(layer, i, k)) / k_scale; }
    uint64_t clamped() const { return m_clamped.load(); }

    /// The raw sums over every layer: low and high words of every pixel and channel
    /// (W·H·3 each; the layers' exact 128-bit sum, as sum() develops it).
    void export_words(std::vector<uint64_t>& lo, std::vector<int64_t>& hi) const {
        const size_t n = size_t(m_width) * m_height * 3;
        lo.resize(n);
        hi.resize(n);
        for (size_t j = 0; j < n; ++j) {
            unsigned __int128 v = 0;
            for (int l = 0; l < m_layers; ++l) v += (unsigned __int128)word(l, j / 3, int(j % 3));
            lo[j] = uint64_t(v);
            hi[j] = int64_t(uint64_t(v >> 64));
        }
    }
    /// Add another film's raw sums (export_words), exactly: 128-bit integer adds, so
    /// films of disjoint sets of splats sum to the film that received them all.
    /// They go into layer 0 (a combined film keeps no groups).
    void add_words(const uint64_t* lo, const int64_t* hi) {
        for (size_t i = 0, n = size_t(m_width) * m_height * 3; i < n; ++i)
            add_sum(i, __int128((unsigned __int128)uint64_t(hi[i]) << 64 | lo[i]));
    }

    /// Add `weight · colour` over `filter`'s footprint around film position p (weights
    /// f(c - p), film/filter.h); the unit box: add(pixel, ...) to the pixel given.
    void add_filtered(const PixelFilter& filter, const Vec2& p, uint32_t pixel, const Spectrum& colour,
                      double weight, int layer = 0) {
        if (filter.unit_box()) {
            add(pixel, colour, weight, layer);
            return;
        }
        filter.footprint(p, m_width, m_height, [&](uint32_t j, double w) { add(j, colour, weight * w, layer); });
    }

    /// std::llround of x for |x| < 2^63 (here at most 2^62), inline instead of a libm
    /// call: the truncation and the remainder are exact, so is the rounding (half away
    /// from zero).
    static int64_t round_half_away(double x) {
        int64_t q = int64_t(x);
        const double r = x - double(q);
        q += int64_t(r >= 0.5) - int64_t(r <= -0.5);
        return q;
    }

private:
    __int128 word(int layer, size_t i, int k) const {
        const size_t j = (size_t(layer) * size_t(m_width) * size_t(m_height) + i) * 3 + size_t(k);
        const unsigned __int128 lo = m_lo[j].load(std::memory_order_relaxed);
        return __int128((unsigned __int128)(m_hi[j].load(std::memory_order_relaxed)) << 64 | lo);
    }

    int m_width, m_height, m_layers;
    std::unique_ptr<std::atomic<uint64_t>[]> m_lo;  ///< fixed-point sums mod 2^64
    std::unique_ptr<std::atomic<int64_t>[]> m_hi;   ///< their high words (carries, signs)
    std::atomic<uint64_t> m_clamped{0};
};

/// A write-combining front of a SplatFilm for one thread's task: a Metropolis chain's
/// splats land on the same few pixels over and over (a rejected proposal splats its
/// current state's pixel again; a small step moves a pixel or two; the gaussian's
/// footprint is 3x3 pixels), and each was three atomic adds per pixel. The buffer sums
/// the quantised splats of recent pixels in 128-bit integers (a direct-mapped table of
/// k_entries pixels) and adds each pixel's sums to the film once, when another pixel takes
/// its entry or at flush(). Integer sums do not depend on order or grouping, so the film
/// holds the same words as with SplatFilm::add (the same image bit for bit) once every
/// buffer is flushed: read the film only after that (the chains' tasks flush at their end).
class SplatBuffer {
public:
    static constexpr size_t k_entries = 256;

    explicit SplatBuffer(SplatFilm& film) : m_film(film), m_entries(new Entry[k_entries]) {}
    SplatBuffer(SplatBuffer&&) = default;
    ~SplatBuffer() { flush(); }

    /// SplatFilm::add through the buffer.
    void add(uint32_t pixel, const Spectrum& colour, double weight, int layer = 0) {
        const float c[3] = {colour.x, colour.y, colour.z};
        int64_t q[3];
        for (int k = 0; k < 3; ++k) q[k] = m_film.quantize(double(c[k]) * weight);
        if ((q[0] | q[1] | q[2]) == 0) return;
        const uint64_t key = uint64_t(layer) * uint64_t(m_film.width()) * uint64_t(m_film.height()) + pixel;
        Entry& e = m_entries[size_t((key * 0x9E3779B97F4A7C15ull) >> 56) & (k_entries - 1)];
        if (e.key != key) {
            write(e);
            e.key = key;
        }
        for (int k = 0; k < 3; ++k) e.sum[k] += q[k];
    }
    /// SplatFilm::add_filtered through the buffer.
    void add_filtered(const PixelFilter& filter, const Vec2& p, uint32_t pixel, const Spectrum& colour, double weight,
                      int layer = 0) {
        if (filter.unit_box()) {
            add(pixel, colour, weight, layer);
            return;
        }
        filter.footprint(p, m_film.width(), m_film.height(),
                         [&](uint32_t j, double w) { add(j, colour, weight * w, layer); });
    }
    /// Every pending sum into the film.
    void flush() {
        if (!m_entries) return;  // moved from
        for (size_t i = 0; i < k_entries; ++i) write(m_entries[i]);
    }

private:
    static constexpr uint64_t k_free = ~uint64_t(0);
    struct Entry {
        uint64_t key = k_free;  ///< layer · W·H + pixel
        __int128 sum[3] = {0, 0, 0};
    };
    void write(Entry& e) {
        if (e.key == k_free) return;
        const size_t pixels = size_t(m_film.width()) * size_t(m_film.height());
        const int layer = int(e.key / pixels);
        const uint32_t pixel = uint32_t(e.key % pixels);
        for (int k = 0; k < 3; ++k)
            if (e.sum[k] != 0) m_film.add_sum(m_film.word_index(layer, pixel, k), e.sum[k]);
        e = Entry();
    }

    SplatFilm& m_film;
    std::unique_ptr<Entry[]> m_entries;
};

}  // namespace cmlt
