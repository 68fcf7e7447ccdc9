/* tvpal_error.c: messages for the error codes of tvpal_error.h. */
#include "tvpal_error.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

const char *tvpal_strerror(int code)
{
    switch (code) {
#define TVPAL_X_CASE(name, value, msg)                                        \
    case value:                                                               \
        return msg;
        TVPAL_ERROR_MAP(TVPAL_X_CASE)
#undef TVPAL_X_CASE
    }
    return "unknown error";
}

int tvpal_diag_set(struct tvpal_diag *diag, int code, const char *fmt, ...)
{
    if (diag) {
        va_list ap;
        va_start(ap, fmt);
        const int n = vsnprintf(diag->msg, sizeof diag->msg, fmt, ap);
        va_end(ap);
        /* A cut message says so, rather than ending mid-word. */
        if (n >= (int)sizeof diag->msg)
            memcpy(diag->msg + sizeof diag->msg - 4, "...", 4);
    }
    return code;
}

void tvpal_diag_copy(char *dst, size_t cap, const char *src)
{
    const size_t n = strlen(src);
    if (n < cap) {
        memcpy(dst, src, n + 1);
        return;
    }
    memcpy(dst, src, cap - 4);
    memcpy(dst + cap - 4, "...", 4);
}
