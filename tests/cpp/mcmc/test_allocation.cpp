// The inner steps allocate nothing: all scratch lives in the pre-sized Workspace.
// This translation unit replaces the global operator new/delete of the test binary with
// counting versions (counting only while a test switches it on).
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "kernel_cases.h"

namespace {
std::atomic<bool> g_counting{false};
std::atomic<std::size_t> g_allocations{0};
}  // namespace

// GCC 12 flags free() on memory from operator new as mismatched, although both are ours.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif

void* operator new(std::size_t size) {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace cmlt::mcmc {
namespace {

using namespace testing;

TEST(Allocation, InnerStepsDoNotAllocate) {
  const CheckerBump f{0.0};
  const KernelParams kernels[] = {{Kernel::small_step, 1, 0.1}, {Kernel::large_step, 1, 0.1},
                                  {Kernel::mtm, 8, 0.1},        {Kernel::seed, 8, 0.1},
                                  {Kernel::bundle, 8, 0.1},     {Kernel::bundle, 16, 0.3}};
  for (const auto& p : kernels) {
    TestRng rng(3);
    auto chain = make_chain(Vec{0.7, 0.3}, f);
    Workspace<Vec> ws(p.tries, chain.x);
    KernelStats stats;
    double total = 0;
    auto splat = [&](const Vec& u, double w) { total += w * u[0]; };
    g_allocations = 0;
    g_counting = true;
    for (int t = 0; t < 2000; ++t) stats.record(do_step(p, chain, f, splat, rng, ws));
    g_counting = false;
    EXPECT_EQ(g_allocations.load(), 0u) << case_name(p);
    EXPECT_GT(total, 0.0);
  }
  // the counter itself works
  g_allocations = 0;
  g_counting = true;
  auto* v = new std::vector<double>(100);
  g_counting = false;
  delete v;
  EXPECT_GE(g_allocations.load(), 1u);
}

}  // namespace
}  // namespace cmlt::mcmc
