/* Harness: the transfer-function ParaView JSON preset (tvpal_tf_parse_paraview), then
 * evaluation across and beyond the data range. */
#include "fuzz_util.h"
#include "tvpal_tf.h"

#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *s = fuzz_strdup(data, size);
    struct tvpal_tf *tf = malloc(sizeof *tf);
    struct tvpal_diag d;
    if (!tf)
        abort();
    if (tvpal_tf_parse_paraview(s, -1.0, 2.0, tf, &d) == 0) {
        float rgba[4];
        for (int i = -2; i <= 12; i++)
            tvpal_tf_eval(tf, -1.0 + 0.25 * i, rgba);
    }
    free(tf);
    free(s);
    return 0;
}
