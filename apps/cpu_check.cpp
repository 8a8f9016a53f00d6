// The start-up check of a portable build: raynode is compiled for an x86-64
// micro-architecture level (RAYNODE_ARCH, default x86-64-v3: AVX2, FMA,
// BMI2). On an older CPU its first AVX2 instruction would die with SIGILL;
// this file, compiled for baseline x86-64 (apps/CMakeLists.txt), runs before
// any other initialiser and says instead what the CPU lacks and how to build
// for it.
#include <cstdio>
#include <cstdlib>

#if defined(RAYNODE_ARCH_LEVEL) && (defined(__x86_64__) || defined(__i386__))
namespace {

__attribute__((constructor(101))) void check_cpu_level() {
  __builtin_cpu_init();
  if (__builtin_cpu_supports(RAYNODE_ARCH_LEVEL)) return;
  std::fprintf(stderr,
               "raynode: error: this program was built for %s, which this CPU does not support; rebuild with "
               "-DRAYNODE_ARCH=x86-64-v2 (or -DRAYNODE_NATIVE=ON)\n",
               RAYNODE_ARCH_LEVEL);
  std::_Exit(1);
}

}  // namespace
#endif
