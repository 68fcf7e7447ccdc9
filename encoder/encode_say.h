/* encode_say.h: how tvpal-encode reports, and how a failure ends it.
 *
 * msg prints a line; die_* print one and end the process with the exit
 * code of enum ending.  The partial output and its lock are libtvpal's,
 * which keeps or removes them before the program reports (tvpal.h).
 * Under MPI a rank that fails before the encode must not just exit (the
 * others would wait): the job registers a relay (say_relay), which takes
 * the failure to rank 0 and ends every rank.
 *
 * The lowest module of the program: it includes no other, and the state
 * those setters keep is this file's own (one process, one report).
 * Program code: reports on stderr and exits.
 */
#ifndef TVPAL_ENCODE_SAY_H
#define TVPAL_ENCODE_SAY_H

#include "tvpal_error.h"

#include <stddef.h>

#define PROG "tvpal-encode"

/* How a message ends the program: MSG_ONLY returns; the others exit with
 * code 2 (usage or bad input: DIE_USAGE before any output, DIE_INPUT
 * found mid-run, the partial output removed by then), or 1 (DIE_FAIL: an
 * output or system failure, a partial output kept for a rerun to
 * resume). */
enum ending { MSG_ONLY, DIE_USAGE, DIE_FAIL, DIE_INPUT };

void msg(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
void die_usage(const char *fmt, ...)
    __attribute__((format(printf, 1, 2), noreturn));
void die_fail(const char *fmt, ...)
    __attribute__((format(printf, 1, 2), noreturn));
void die_input(const char *fmt, ...)
    __attribute__((format(printf, 1, 2), noreturn));

/* The text of a library error for a message: the code's message, then the
 * diag's detail in parentheses when it has one (a static buffer). */
const char *lib_error(int rc, const struct tvpal_diag *d);

/* This process is rank `rank` of a job: messages of ranks above 0 say
 * their rank, and plain messages (the same on every rank) only rank 0
 * prints. */
void say_as_rank(int rank);

/* While set (fn non-NULL), a die_* hands its ending and text to fn(ctx,
 * how, text), which must not return (it ends every rank).  NULL: die_*
 * print and exit themselves. */
typedef void (*say_relay_fn)(void *ctx, enum ending how, const char *text);
void say_relay(say_relay_fn fn, void *ctx);

#endif
