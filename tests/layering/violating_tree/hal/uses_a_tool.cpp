// A fixture of tests/layering: a hal/ file that includes from tools/ (must be reported).
#include "tools/common/command_line.hpp"
