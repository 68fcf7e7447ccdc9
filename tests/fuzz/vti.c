/* Harness: the VTK XML ImageData (.vti, .pvd, .pvti) input reader through tvpal_input.h on a
 * temporary file (input_common.h). */
#include "input_common.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return fuzz_input(data, size, TVPAL_IN_VTI, "in.vti");
}
