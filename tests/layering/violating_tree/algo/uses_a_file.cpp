// A fixture of tests/layering: an algo/ file that breaks two rules (must be reported).
#include <fstream>

#include "hal/io/file_util.hpp"
