# The layering rules (README "Where each part lives", docs/testing.md), checked on the
# #include lines of every source file under ROOT (cmake -DROOT=DIR -P check_includes.cmake):
#   algo/          nothing from hal/, tools/, firmware_like/, tests/, and no header of files,
#                  devices or threads (<fstream> <filesystem> <iostream> <thread> <mutex> <linux/...>
#                  <sys/...> <unistd.h> <fcntl.h>); it takes views and returns results;
#   hal/           nothing from tools/, firmware_like/, tests/;
#   firmware_like/ nothing from tools/, tests/;
#   tools/         nothing from firmware_like/, tests/ (tools build on algo and hal only).
# No exceptions: what the platform reports (the CPU's NEON bit) is read in hal/cpu/ and handed to
# algo (lkSelectKernels). Exits with an error listing every violation.
cmake_minimum_required(VERSION 3.25)
if(NOT ROOT)
  message(FATAL_ERROR "check_includes.cmake: -DROOT=<source dir> is required")
endif()

set(rule_algo "^(hal|tools|firmware_like|tests)/|^(fstream|filesystem|iostream|thread|mutex|unistd\\.h|fcntl\\.h)$|^(linux|sys)/")
set(rule_hal "^(tools|firmware_like|tests)/")
set(rule_firmware_like "^(tools|tests)/")
set(rule_tools "^(firmware_like|tests)/")

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
      if(header MATCHES "${rule_${layer}}")
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
