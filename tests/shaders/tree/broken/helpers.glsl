// A helper that includes a file that does not exist.

#include "missing/constants.glsl"
