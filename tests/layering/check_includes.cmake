# The layering rules (README "Where each part lives", docs/testing.md), checked on the
# #include lines of every source file under ROOT (cmake -DROOT=DIR -P check_includes.cmake):
#   algo/          nothing from hal/, tools/, firmware_like/, tests/, and no header of files,
#                  devices or threads (<fstream> <filesystem> <iostream> <thread> <mutex> <linux/...>
#                  <sys/...> <unistd.h> <fcntl.h>); it takes views and returns results;
#   hal/           nothing from tools/, firmware_like/, tests/;
#   firmware_like/ nothing from tools/, tests/;
#   tools/         nothing from tests/.
# One exception, listed here with its reason: algo/flow/lk_kernels_neon32.cpp reads the CPU's NEON
# bit with getauxval(AT_HWCAP) from <sys/auxv.h> (a read of the process's auxiliary vector, no
# file or device; the ARMv7 counterpart of x86-64's __builtin_cpu_supports, see lk_kernels.hpp).
# Exits with an error listing every violation.
cmake_minimum_required(VERSION 3.25)
if(NOT ROOT)
  message(FATAL_ERROR "check_includes.cmake: -DROOT=<source dir> is required")
endif()

set(rule_algo "^(hal|tools|firmware_like|tests)/|^(fstream|filesystem|iostream|thread|mutex|unistd\\.h|fcntl\\.h)$|^(linux|sys)/")
set(rule_hal "^(tools|firmware_like|tests)/")
set(rule_firmware_like "^(tools|tests)/")
set(rule_tools "^tests/")
set(allowed "algo/flow/lk_kernels_neon32.cpp:sys/auxv.h")

get_filename_component(ROOT "${ROOT}" ABSOLUTE)
set(violations "")
set(checked 0)
foreach(layer IN ITEMS algo hal firmware_like tools)
  file(GLOB_RECURSE sources RELATIVE "${ROOT}" "${ROOT}/${layer}/*.cpp" "${ROOT}/${layer}/*.hpp"
       "${ROOT}/${layer}/*.h" "${ROOT}/${layer}/*.c")
  foreach(source IN LISTS sources)
    math(EXPR checked "${checked} + 1")
    file(STRINGS "${ROOT}/${source}" lines REGEX "^[ \t]*#[ \t]*include[ \t]*[<\"]")
    foreach(line IN LISTS lines)
      string(REGEX REPLACE "^[ \t]*#[ \t]*include[ \t]*[<\"]([^>\"]+)[>\"].*$" "\\1" header "${line}")
      if(header MATCHES "${rule_${layer}}" AND NOT "${source}:${header}" IN_LIST allowed)
        string(APPEND violations "  ${source}: #include ${header}\n")
      endif()
    endforeach()
  endforeach()
endforeach()

if(checked EQUAL 0)
  message(FATAL_ERROR "check_includes.cmake: no source files under ${ROOT}")
endif()
if(violations)
  message(FATAL_ERROR "layering: forbidden includes:\n${violations}")
endif()
message(STATUS "layering: ${checked} files, no forbidden include")
