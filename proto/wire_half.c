/* wire_half.c: IEEE 754 binary16 <-> float for TEX_PATCH texels
 * (GL_HALF_FLOAT): the conversions of common/half.h, bit-exact on every
 * build. */
#include "proto/wire.h"

#include "common/half.h"

uint16_t wire_half_from_float(float f)
{
    return half_from_float(f);
}

float wire_half_to_float(uint16_t h)
{
    return half_to_float(h);
}
