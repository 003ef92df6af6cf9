# Sourced by the CI stages that run the suite slowly (.ci/cross_aarch64.sh under qemu,
# .ci/sanitizers.sh under ASan): the solver's whole-clip accuracy sweeps, 50-110 s each under
# qemu and 100-380 s under ASan, which those stages leave to the native test stage. A ctest -E
# regex with '.' for spaces, so it survives word splitting.
solver_sweeps='^(The.solve.does.not.depend.on.small.shifts|Exact.orbit|Orbit.with.a.wandering.target|Dolly..forward.motion.|Handheld.with.the.focal.unknown)'
