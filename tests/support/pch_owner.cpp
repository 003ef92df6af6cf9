// The owner of the test binaries' shared precompiled header (tests/CMakeLists.txt,
// EPITRACK_TEST_PCH): a binary of its own, compiled with the test binaries' options, so that
// building any one test binary compiles the header once and never builds another test's sources.
int main() { return 0; }
