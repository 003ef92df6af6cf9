# Compile options shared by every epitrack target.
#
# -ffp-contract=off everywhere: no fused multiply-add contraction, so floating-point results of the
# front end are bit-identical on x86-64 and ARM (aarch64 compilers contract by default).
add_compile_options(-ffp-contract=off)

# 32-bit targets (armhf): large files and 64-bit time. Without _FILE_OFFSET_BITS=64, readdir fails
# with EOVERFLOW on ext4 (its directory offsets are 64-bit hashes) and files over 2 GB cannot be
# opened; without _TIME_BITS=64 (glibc 2.34+, which accepts it only together with the former),
# time_t and the timestamps it carries overflow in 2038. Every target of the project gets both, so
# off_t, time_t and the structs holding them (struct stat, struct timeval in struct v4l2_buffer)
# have one layout across the libraries. V4L2: the ioctl numbers encode the struct size and come
# from the same headers, so VIDIOC_QBUF/DQBUF carry the 64-bit-time v4l2_buffer (80 bytes), which
# Linux 5.6 and later accept (natively on 32-bit kernels, through the compat layer on 64-bit ones);
# tests/hal/platform_abi_test.cpp checks these sizes on the target.
if(CMAKE_SIZEOF_VOID_P EQUAL 4)
  add_compile_definitions(_FILE_OFFSET_BITS=64 _TIME_BITS=64)
  include(CheckCXXSourceCompiles)
  set(CMAKE_REQUIRED_DEFINITIONS -D_FILE_OFFSET_BITS=64 -D_TIME_BITS=64)
  check_cxx_source_compiles("
    #include <ctime>
    #include <sys/types.h>
    static_assert(sizeof(off_t) == 8 && sizeof(time_t) == 8);
    int main() { return 0; }" EPITRACK_HAVE_64BIT_OFF_AND_TIME)
  unset(CMAKE_REQUIRED_DEFINITIONS)
  if(NOT EPITRACK_HAVE_64BIT_OFF_AND_TIME)
    message(WARNING "This 32-bit C library has no 64-bit off_t and time_t (glibc older than 2.34?): "
                    "files over 2 GB and timestamps after 2038 will fail")
  endif()
endif()

add_library(epitrack_warnings INTERFACE)
target_compile_options(epitrack_warnings INTERFACE
  -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wno-sign-conversion -Wnon-virtual-dtor
  -Wcast-align -Woverloaded-virtual -Wnull-dereference -Wdouble-promotion -Wformat=2
  $<$<BOOL:${EPITRACK_WERROR}>:-Werror>)
if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(arm|ARM)")
  # GCC notes on 32-bit ARM that passing some structs changed in GCC 7.1: nothing here links with
  # code built by GCC 6 or older, and the notes buried the real diagnostics of the armhf build.
  target_compile_options(epitrack_warnings INTERFACE -Wno-psabi)
endif()

# Sanitizers: a list; incompatible combinations are refused.
if(EPITRACK_SANITIZERS)
  set(_san "${EPITRACK_SANITIZERS}")
  if(("thread" IN_LIST _san AND "address" IN_LIST _san) OR
     ("memory" IN_LIST _san AND ("address" IN_LIST _san OR "thread" IN_LIST _san)))
    message(FATAL_ERROR "EPITRACK_SANITIZERS: '${_san}' combines sanitizers that cannot run together")
  endif()
  foreach(s IN LISTS _san)
    if(NOT s MATCHES "^(address|undefined|thread|memory|leak)$")
      message(FATAL_ERROR "EPITRACK_SANITIZERS: unknown sanitizer '${s}'")
    endif()
  endforeach()
  string(REPLACE ";" "," _san_flags "${_san}")
  add_compile_options(-fsanitize=${_san_flags} -fno-omit-frame-pointer -fno-sanitize-recover=all)
  add_link_options(-fsanitize=${_san_flags})
endif()

# Helper: give a target the project's warnings and include root.
function(epitrack_target_defaults target)
  target_link_libraries(${target} PRIVATE $<BUILD_INTERFACE:epitrack_warnings>)
endfunction()

# Build time (docs/testing.md, "Build time"): parsing Eigen costs about 1.2 s per translation
# unit, more than some of the units' own code. algo/ and the commands whose units all include it
# (bench, solve, synth) precompile <Eigen/Dense> once per target (GCC checks the header is used:
# -Winvalid-pch is an error under -Werror). Not tools/export and tools/render: with the header
# GCC 12 reports its known false -Warray-bounds on inlined std::string copies there.
# The results do not change (byte-identical solves and tracks, 2026-12-06). EPITRACK_PCH=OFF
# compiles without (clang-tidy's configure-only build).
option(EPITRACK_PCH "Precompile Eigen once per library" ON)
function(epitrack_eigen_pch target)
  if(EPITRACK_PCH)
    target_precompile_headers(${target} PRIVATE <Eigen/Dense>)
  endif()
endfunction()
