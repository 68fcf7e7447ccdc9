/* tvpal_cli.h: helpers shared by the programs: number parsing and
 * progress-line formatting (the clock is tvpal_clock.h).  Nothing here prints. */
#ifndef TVPAL_CLI_H
#define TVPAL_CLI_H

#include <stddef.h>
#include <stdint.h>

/* Exit codes of every tvpal program. */
enum { TVPAL_EXIT_OK = 0, TVPAL_EXIT_FAIL = 1, TVPAL_EXIT_USAGE = 2 };

/* Whole decimal number in [lo, hi]; 0 or -1. */
int tvpal_parse_u32(const char *s, uint32_t lo, uint32_t hi, uint32_t *out);
/* Finite double; 0 or -1. */
int tvpal_parse_double(const char *s, double *out);
/* Finite double in [lo, hi]; 0 or -1 (NaN, infinities and overflow are
 * refused). */
int tvpal_parse_double_in(const char *s, double lo, double hi, double *out);
/* Exactly n finite doubles joined by sep ("1,2,3"), each as
 * tvpal_parse_double takes it (no empty part, trailing text or overflow);
 * 0 or -1 (out may be partly written then). */
int tvpal_parse_doubles(const char *s, char sep, unsigned n, double *out);
/* Two whole decimal numbers joined by sep ("WxH", "A:B"), each in
 * [lo, hi] as tvpal_parse_u32 takes them: no sign, space, empty part,
 * trailing text or overflow.  0 or -1; out is left as it was on -1. */
int tvpal_parse_u32_pair(const char *s, char sep, uint32_t lo, uint32_t hi,
                         uint32_t out[2]);
/* "x" | "y" | "z" -> 0..2; -1 otherwise. */
int tvpal_parse_axis(const char *s);


/* Formats "[#####.....]  45%  45/99 steps  12.3 Mvox-steps/s  ETA 1m23s"
 * (bar when width > 0) into buf. */
void tvpal_progress_format(char *buf, size_t cap, uint64_t done,
                           uint64_t total, const char *unit, double rate,
                           const char *rate_unit, double eta_s, int width);

/* Natural order of file names: runs of digits compare by their numeric
 * value (density_2 < density_10), everything else byte by byte; <0, 0, >0
 * as strcmp. */
int tvpal_natural_cmp(const char *a, const char *b);

/* Sets of axes, as a mask: bit 0 x, bit 1 y, bit 2 z (the manifest's
 * TVPAL_AXIS_BIT, tvpal.h's TVPAL_AXIS_X, _Y, _Z).
 *
 * A set as the manifest's axes key and tvpal-encode --axes write it: the
 * letters x, y, z, each at most once, in any order, with spaces or tabs
 * between them or not ("z", "xz", "x y z"); at least one.  0 with *mask
 * set (a bit per letter), or TVPAL_E_INVAL (*mask left as it was). */
int tvpal_axes_parse(const char *s, uint32_t *mask);

/* The canonical text of mask (1..7): its letters in x, y, z order, no
 * spaces ("z", "xz", "xyz"), into buf (4 bytes at least); "" for a mask
 * outside 1..7.  Returns buf. */
char *tvpal_axes_format(uint32_t mask, char buf[4]);

/* Number of axes in mask (0..3). */
unsigned tvpal_axes_count(uint32_t mask);

#endif
