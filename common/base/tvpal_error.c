/* tvpal_error.c: messages for the error codes of tvpal_error.h. */
#include "tvpal_error.h"

#include <stdarg.h>
#include <stdio.h>

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
        vsnprintf(diag->msg, sizeof diag->msg, fmt, ap);
        va_end(ap);
    }
    return code;
}
