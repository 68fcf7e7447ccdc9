/* encode_say.c: tvpal-encode's messages and endings (encode_say.h). */
#include "encode_say.h"
#include "tvpal_cli.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

/* What a die_* undoes and where it goes: this process's, set by the
 * program's steps (encode_say.h). */
static struct {
    int rank;               /* -1: one process */
    say_relay_fn relay;
    void *relay_ctx;
} g_say = {-1, NULL, NULL};

void say_as_rank(int rank)
{
    g_say.rank = rank;
}

void say_relay(say_relay_fn fn, void *ctx)
{
    g_say.relay = fn;
    g_say.relay_ctx = ctx;
}

static void say(enum ending how, const char *fmt, va_list ap)
{
    if (g_say.relay && how != MSG_ONLY) {
        char text[900];
        vsnprintf(text, sizeof text, fmt, ap);
        g_say.relay(g_say.relay_ctx, how, text);
        abort(); /* a relay does not return */
    }
    if (how == MSG_ONLY && g_say.rank > 0)
        return; /* warnings are the same on every rank: rank 0 says them */
    fputs(PROG ": ", stderr);
    if (g_say.rank > 0)
        fprintf(stderr, "rank %d: ", g_say.rank);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    if (how == MSG_ONLY)
        return;
    exit(how == DIE_FAIL ? TVPAL_EXIT_FAIL : TVPAL_EXIT_USAGE);
}

#define TVPAL_SAY_FN(name, how)                                               \
    void name(const char *fmt, ...)                                           \
    {                                                                         \
        va_list ap;                                                           \
        va_start(ap, fmt);                                                    \
        say(how, fmt, ap);                                                    \
        if (how != MSG_ONLY)                                                  \
            exit(TVPAL_EXIT_FAIL); /* not reached: say() exited */         \
        va_end(ap);                                                           \
    }
TVPAL_SAY_FN(msg, MSG_ONLY)
TVPAL_SAY_FN(die_usage, DIE_USAGE)
TVPAL_SAY_FN(die_fail, DIE_FAIL)
TVPAL_SAY_FN(die_input, DIE_INPUT)

/* Library calls promise nothing about errno, so their cause comes from
 * here, never strerror(errno).  Reports are made by one thread. */
const char *lib_error(int rc, const struct tvpal_diag *d)
{
    static char buf[sizeof ((struct tvpal_diag *)0)->msg + 64];
    if (d && d->msg[0])
        snprintf(buf, sizeof buf, "%s (%s)", tvpal_strerror(rc), d->msg);
    else
        snprintf(buf, sizeof buf, "%s", tvpal_strerror(rc));
    return buf;
}
