// A fixture of tests/layering: an algo/ file that reads the platform (must be reported; the CPU's
// features are read in hal/cpu/).
#include <sys/auxv.h>
