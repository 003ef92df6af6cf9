# Compile options shared by every epitrack target.
#
# -ffp-contract=off everywhere: no fused multiply-add contraction, so floating-point results of the
# front end are bit-identical on x86-64 and ARM (aarch64 compilers contract by default).
add_compile_options(-ffp-contract=off)

add_library(epitrack_warnings INTERFACE)
target_compile_options(epitrack_warnings INTERFACE
  -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wno-sign-conversion -Wnon-virtual-dtor
  -Wcast-align -Woverloaded-virtual -Wnull-dereference -Wdouble-promotion -Wformat=2
  $<$<BOOL:${EPITRACK_WERROR}>:-Werror>)

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
