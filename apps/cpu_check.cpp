// The start-up check of a portable build: raynode is compiled for an x86-64
// micro-architecture level (RAYNODE_ARCH, default x86-64-v3: AVX2, FMA,
// BMI2). On an older CPU its first AVX2 instruction would die with SIGILL;
// this file, compiled for baseline x86-64 (apps/CMakeLists.txt), runs before
// any other initialiser and says instead what the CPU lacks and how to build
// for it.
#include <cstdio>
#include <cstdlib>
#include <cstring>

#if defined(RAYNODE_ARCH_LEVEL) && (defined(__x86_64__) || defined(__i386__))
namespace {

/// The features a level needs that the compilers' __builtin_cpu_supports
/// names (GCC 12 and clang 14 both know these; clang 14 knows no level names).
bool supports_level(const char* level) {
  const bool v2 = __builtin_cpu_supports("sse3") && __builtin_cpu_supports("ssse3") &&
                  __builtin_cpu_supports("sse4.1") && __builtin_cpu_supports("sse4.2") &&
                  __builtin_cpu_supports("popcnt");
  const bool v3 = v2 && __builtin_cpu_supports("avx") && __builtin_cpu_supports("avx2") &&
                  __builtin_cpu_supports("bmi") && __builtin_cpu_supports("bmi2") && __builtin_cpu_supports("fma");
  const bool v4 = v3 && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
                  __builtin_cpu_supports("avx512cd") && __builtin_cpu_supports("avx512dq") &&
                  __builtin_cpu_supports("avx512vl");
  if (std::strcmp(level, "x86-64-v2") == 0) return v2;
  if (std::strcmp(level, "x86-64-v3") == 0) return v3;
  if (std::strcmp(level, "x86-64-v4") == 0) return v4;
  return true;
}

__attribute__((constructor(101))) void check_cpu_level() {
  __builtin_cpu_init();
  if (supports_level(RAYNODE_ARCH_LEVEL)) return;
  std::fprintf(stderr,
               "raynode: error: this program was built for %s, which this CPU does not support; rebuild with "
               "-DRAYNODE_ARCH=x86-64-v2 (or -DRAYNODE_NATIVE=ON)\n",
               RAYNODE_ARCH_LEVEL);
  std::_Exit(1);
}

}  // namespace
#endif
