/* encode_say.h: how tvpal-encode reports, and how a failure ends it.
 *
 * msg prints a line; die_* print one and end the process with the exit
 * code of enum ending, first undoing what must not outlive a failure: the
 * partial output when the input was bad (say_remove_on_bad_input) and the
 * output's lock (say_release_lock_at_exit).  Under MPI a failing rank must
 * not just exit (the others would wait): the job's rounds register a relay
 * (say_relay), which takes the failure to rank 0 and ends every rank.
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
 * code 2 (usage or bad input, before any output), 1 (output or system
 * failure: a partial output is kept for a rerun to resume) or 2 after
 * removing the partial output (bad input found mid-run: a rerun would fail
 * the same way, so nothing partial stays behind). */
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

/* The directory die_input removes (bad input: a rerun would fail the same
 * way), or NULL; the caller's string, kept until the process ends. */
void say_remove_on_bad_input(const char *dir);
/* Removes that directory now (a relay ending a job for bad input). */
void say_remove_bad_input_output(void);

/* The lock (tvpal_lock_take) released whenever a die_* ends the process;
 * path the caller's, kept until the process ends. */
void say_release_lock_at_exit(const char *path, int fd);
void say_release_lock_now(void);

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
