/* play_timing.c: the table of timing columns (see play_timing.h). */
#include "play_timing.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

void play_timing_aggregate(const struct play_rank_rec *r, int n,
                           struct play_rank_rec *o)
{
    memset(o, 0, sizeof *o);
    for (int i = 0; i < n; i++) {
        const struct play_rank_rec *q = &r[i];
        o->io = fmax(o->io, q->io);
        o->stream = fmax(o->stream, q->stream);
        o->up = fmax(o->up, q->up);
        o->draw = fmax(o->draw, q->draw);
        o->read = fmax(o->read, q->read);
        o->enc = fmax(o->enc, q->enc);
        o->exch = fmax(o->exch, q->exch);
        o->blend = fmax(o->blend, q->blend);
        o->comp = fmax(o->comp, q->comp);
        o->gath = fmax(o->gath, q->gath);
        o->total = fmax(o->total, q->total);
        o->classify = fmax(o->classify, q->classify);
        o->accum = fmax(o->accum, q->accum);
        o->warp = fmax(o->warp, q->warp);
        o->bytes_read += q->bytes_read;
        o->bytes_needed += q->bytes_needed;
        o->bytes_sent = q->bytes_sent > o->bytes_sent ? q->bytes_sent : o->bytes_sent;
        o->bytes_sent_total += q->bytes_sent;
        o->gather_bytes += q->gather_bytes;
        o->pixels = q->pixels > o->pixels ? q->pixels : o->pixels;
        if (q->rc < 0 && o->rc >= 0)
            o->rc = q->rc;
        o->fatal |= q->fatal;
    }
}

/* ------------------------------------------------------------ the table */

enum col_kind { C_U32, C_INT, C_CHAR, C_MS, C_U64, C_REAL };
/* What the summary line makes of a column over the frames. */
enum col_sum { S_NONE, S_MEAN, S_SUM, S_LAST };

struct column {
    const char *name;
    enum col_kind kind;   /* C_MS: "%.3f", C_REAL: "%.17g"; integers as
                           * themselves */
    size_t off;           /* in struct play_row */
    enum col_sum sum;
};

#define R(field) offsetof(struct play_row, field)
#define A(field) offsetof(struct play_row, agg.field)

/* In CSV order; every column's meaning is in the man page (TIMING CSV). */
static const struct column columns[] = {
    {"step", C_U32, R(step), S_NONE},
    {"axis", C_CHAR, R(axis), S_NONE},
    {"io_ms", C_MS, A(io), S_MEAN},
    {"stream_ms", C_MS, A(stream), S_MEAN},
    {"upload_ms", C_MS, A(up), S_MEAN},
    {"draw_ms", C_MS, A(draw), S_MEAN},
    {"readback_ms", C_MS, A(read), S_MEAN},
    {"total_ms", C_MS, A(total), S_NONE},
    {"bytes_read", C_U64, A(bytes_read), S_SUM},
    {"slices_drawn", C_U32, R(drawn), S_NONE},
    {"slices_skipped", C_U32, R(skipped), S_NONE},
    {"slice_uploads", C_U32, R(uploads), S_NONE},
    {"axis_switch_ms", C_MS, R(axis_switch_ms), S_NONE},
    {"jump", C_INT, R(jump), S_NONE},
    {"stride", C_U32, R(stride), S_NONE},
    {"encode_ms", C_MS, A(enc), S_NONE},
    {"exchange_ms", C_MS, A(exch), S_NONE},
    {"blend_ms", C_MS, A(blend), S_NONE},
    {"composite_ms", C_MS, A(comp), S_MEAN},
    {"gather_ms", C_MS, A(gath), S_NONE},
    {"bytes_sent_max", C_U64, A(bytes_sent), S_NONE},
    {"bytes_sent_total", C_U64, A(bytes_sent_total), S_NONE},
    {"gather_bytes_total", C_U64, A(gather_bytes), S_NONE},
    {"pixels_blended_max", C_U64, A(pixels), S_NONE},
    {"ranks", C_INT, R(ranks), S_LAST},
    {"sw_classify_ms", C_MS, A(classify), S_NONE},
    {"sw_composite_ms", C_MS, A(accum), S_NONE},
    {"sw_warp_ms", C_MS, A(warp), S_NONE},
    {"psnr_ref", C_MS, R(psnr), S_MEAN},
    {"time", C_REAL, R(time), S_NONE},
    {"records_staged", C_U32, R(staged), S_NONE},
    {"level", C_U32, R(level), S_NONE},
    {"full_ms", C_MS, R(full_ms), S_NONE},
    {"bytes_needed", C_U64, A(bytes_needed), S_NONE},
};
#define NCOLS (sizeof columns / sizeof *columns)

/* The summary line's columns, in its order (after fps= and frames=). */
static const char *const summary_cols[] = {
    "io_ms", "stream_ms", "upload_ms", "draw_ms", "readback_ms", "composite_ms", "ranks",
    "bytes_read"};

_Static_assert(NCOLS <= sizeof ((struct play_totals *)0)->sum /
                            sizeof (double), "play_totals.sum too small");

static double value(const struct column *c, const struct play_row *row)
{
    const char *p = (const char *)row + c->off;
    switch (c->kind) {
    case C_U32: return *(const uint32_t *)(const void *)p;
    case C_INT: return *(const int *)(const void *)p;
    case C_CHAR: return *p;
    case C_MS:
    case C_REAL: return *(const double *)(const void *)p;
    case C_U64: return (double)*(const uint64_t *)(const void *)p;
    }
    return 0;
}

static void print_value(FILE *f, const struct column *c, const char *p)
{
    switch (c->kind) {
    case C_U32: fprintf(f, "%u", *(const uint32_t *)(const void *)p); break;
    case C_INT: fprintf(f, "%d", *(const int *)(const void *)p); break;
    case C_CHAR: fputc(*p, f); break;
    case C_MS: fprintf(f, "%.3f", *(const double *)(const void *)p); break;
    case C_REAL: fprintf(f, "%.17g", *(const double *)(const void *)p); break;
    case C_U64:
        fprintf(f, "%llu",
                (unsigned long long)*(const uint64_t *)(const void *)p);
        break;
    }
}

void play_timing_csv_header(FILE *f)
{
    for (size_t i = 0; i < NCOLS; i++)
        fprintf(f, "%s%s", i ? "," : "", columns[i].name);
    fputc('\n', f);
}

void play_timing_csv_row(FILE *f, const struct play_row *row)
{
    for (size_t i = 0; i < NCOLS; i++) {
        if (i)
            fputc(',', f);
        print_value(f, &columns[i], (const char *)row + columns[i].off);
    }
    fputc('\n', f);
}

void play_timing_add(struct play_totals *t, const struct play_row *row)
{
    for (size_t i = 0; i < NCOLS; i++) {
        double v = value(&columns[i], row);
        if (columns[i].sum == S_LAST)
            t->sum[i] = v;
        else if (columns[i].sum != S_NONE)
            t->sum[i] += v;
    }
    t->frames++;
}

static size_t column_index(const char *name)
{
    size_t i = 0;
    while (i < NCOLS && strcmp(columns[i].name, name))
        i++;
    return i;
}

void play_timing_summary(FILE *f, const struct play_totals *t, double fps)
{
    fprintf(f, "fps=%.3f frames=%u", fps, t->frames);
    for (size_t k = 0; k < sizeof summary_cols / sizeof *summary_cols; k++) {
        size_t i = column_index(summary_cols[k]);
        const struct column *c = &columns[i];
        double v = t->sum[i];
        if (c->sum == S_MEAN)
            v /= t->frames ? t->frames : 1;
        fprintf(f, " %s=", c->name);
        if (c->kind == C_MS)
            fprintf(f, "%.3f", v);
        else if (c->kind == C_U64)
            fprintf(f, "%llu", (unsigned long long)v);
        else
            fprintf(f, "%d", (int)v);
    }
}

double play_timing_mean_psnr(const struct play_totals *t)
{
    return t->sum[column_index("psnr_ref")] / (t->frames ? t->frames : 1);
}
