// A fixture of tests/layering: a tools/ file that includes from firmware_like/ (must be reported).
#include "firmware_like/device_config.hpp"
