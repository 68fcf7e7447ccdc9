/* Harness: manifest text (tvpal_manifest_load).  A manifest that loads
 * must format, and its formatted text must load again (a round trip). */
#include "fuzz_util.h"
#include "tvpal_manifest.h"

#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    struct tvpal_manifest m;
    struct tvpal_diag d;
    const char *p = fuzz_write("manifest.txt", data, size);
    if (tvpal_manifest_load(p, &m, &d) < 0)
        return 0;
    char *text = NULL;
    if (tvpal_manifest_format(&m, &text) == 0) {
        struct tvpal_manifest again;
        p = fuzz_write("again.txt", text, strlen(text));
        if (tvpal_manifest_load(p, &again, &d) < 0)
            abort();    /* what format writes, load must read */
        tvpal_manifest_clear(&again);
    }
    free(text);
    tvpal_manifest_clear(&m);
    return 0;
}
