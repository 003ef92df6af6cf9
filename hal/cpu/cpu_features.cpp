#include "hal/cpu/cpu_features.hpp"

#include "algo/flow/simd_isa.hpp"

#if EPITRACK_LK_NEON_ARMV7
#include <sys/auxv.h>
#endif

namespace epitrack::hal {

CpuVectorIsa cpuVectorIsa() {
#if EPITRACK_LK_NEON_ARMV7
  // A read of the process's auxiliary vector (no file, no device): the ARMv7 counterpart of
  // x86-64's __builtin_cpu_supports.
  return (::getauxval(AT_HWCAP) & HWCAP_ARM_NEON) != 0 ? CpuVectorIsa::kNeon
                                                       : CpuVectorIsa::kBaseline;
#else
  return CpuVectorIsa::kBaseline;
#endif
}

void selectKernelsForThisCpu() { lkSelectKernels(cpuVectorIsa()); }

}  // namespace epitrack::hal
