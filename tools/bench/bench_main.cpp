// epitrack-bench: benchmarks printing one JSON object per line (ARCHITECTURE.md "Commands").
#include <cstdio>
#include <cstring>
#include <string>

#include "hal/cpu/cpu_features.hpp"
#include "tools/bench/bench_registry.hpp"

int main(int argc, char** argv) {
  epitrack::hal::selectKernelsForThisCpu();
  auto& reg = epitrack::bench::registry();
  const auto usage = [&](std::FILE* out) {
    std::fprintf(out,
                 "usage: epitrack-bench SUBCOMMAND [INPUT] [--repeat N] [--threads 1] [options]\n\n"
                 "Times epitrack's stages (and, when built with -DEPITRACK_BENCH_OPENCV=ON, "
                 "OpenCV's equivalents on\n"
                 "the same data in the same run). Prints one JSON object per line: medians, means "
                 "and p95 of the\n"
                 "repeated runs, and an \"impl\": \"ratio\" line with opencv_ms / "
                 "epitrack_ms.\nExit: 0 done, 1 a run failed, 2 bad command line or unusable "
                 "INPUT.\n\nsubcommands:\n");
    for (const auto& [name, e] : reg) std::fprintf(out, "  %-10s %s\n", name.c_str(), e.summary);
    std::fprintf(out, "\n'epitrack-bench SUBCOMMAND --help' lists its options.\n");
  };
  if (argc < 2) {
    std::fprintf(stderr, "epitrack-bench: missing SUBCOMMAND (see --help)\n");
    return 2;
  }
  if (std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0) {
    usage(stdout);
    return 0;
  }
  const auto it = reg.find(argv[1]);
  if (it == reg.end()) {
    std::fprintf(stderr, "epitrack-bench: unknown subcommand '%s' (see --help)\n", argv[1]);
    return 2;
  }
  return it->second.run(argc - 1, argv + 1);
}
