/* Harness: the transfer-function text format (tvpal_tf_parse_text), then
 * evaluation across and beyond the value range (tf_common.h). */
#include "fuzz_util.h"
#include "tf_common.h"

#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *s = fuzz_strdup(data, size);
    fuzz_tf(s, tvpal_tf_parse_text);
    free(s);
    return 0;
}
