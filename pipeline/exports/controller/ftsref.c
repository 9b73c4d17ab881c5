/* ftsref: what a controller does with ftsweep's files, in plain C99 (docs/controllers.md).
 *
 * Built against a table header (-DFTS_HEADER="file.h" -DFTS_PREFIX=NAME -DFTS_TABLE=name_table):
 *   reads pairs of doubles from stdin -- (rho [um], theta [deg]) for a ring, (x [um], y [um])
 *   for a mesh -- and writes the bilinear lookup (model section 3, eq. 2) of the header's own
 *   table and macros [um] as doubles to stdout.
 * Built without: ftsref PROGRAM M IX90_MS G93_SECONDS C_WRAPS POWER [I42] reads a path program as its
 *   controller's manual describes it and writes the axes the program moves (C, X, Y, Z, W, in
 *   that order: first a double holding their bit mask 1, 2, 4, 8, 16), for every segment k of
 *   every cut and j = 0..M-1, at the segment's time fraction u = (j + 0.5)/M:
 *   - PMAC (Turbo PMAC Software Reference, "PVT", "SPLINE1", "INC", "Ix90"): words with or
 *     without spaces, ABS/INC, RAPID to the start (the cut starts there at rest), PVT<ms>
 *     moves AXISpos:vel whose velocities are in units per IX90_MS ms, evaluated as the
 *     manual's cubic in time p(t) = p0 + v0 t + c2 t^2 + c3 t^3 through the end positions
 *     and velocities; SPLINE1 moves timed by TM<ms> (I42 0, the default) or TA<ms> (I42 1),
 *     as the manual's I42 entry says, PVT<ms> setting the time in either (Power PMAC,
 *     POWER 1: spline<ms>), evaluated by
 *     the uniform cubic B-spline's basis functions over the control points with the
 *     manual's added pieces (a zero-distance segment of TA at each end: from and to rest,
 *     one segment more at each end);
 *   - G-code (RS274NGC, ISO STS as a Moore reads it): G93 G01 blocks, linear in time, F the
 *     block's time in seconds (G93_SECONDS 1) or 1/minutes (0); a cut is a run of G93 feed
 *     blocks that turn C; a G93 block that moves no axis stands still, one that moves other
 *     axes only is not a cut; C printed modulo 360 (C_WRAPS 1) turns the shorter way round;
 *     the profile's power-on modes (POWER_ON, a block of G words run before the file, e.g.
 *     "G01 G94 G90"), G90/G91, G04 dwells (no move), G52 local offsets (G52 alone cancels
 *     them), M2/M30 ending the program. Not read, refused naming the line: macro statements
 *     (#, WHILE, IF, GOTO), block delete (/); axis words without a point are read as mm.
 * Compile with -std=c99 -ffp-contract=off so that no multiply-add is fused.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <ctype.h>

#ifdef FTS_HEADER
#include FTS_HEADER

#define FTS_CAT2(a, b) a##_##b
#define FTS_CAT(a, b) FTS_CAT2(a, b)
#define M(x) FTS_CAT(FTS_PREFIX, x)

static double cell(long i, long j) { return (double)FTS_TABLE[i][j] * M(UNIT_NM) / 1000.0; }

static double lookup(double a, double b)
{
    const long n0 = M(ROWS), n1 = M(COLS);
    double u = (a - M(ORIGIN0)) / M(PITCH0), v = (b - M(ORIGIN1)) / M(PITCH1);
    double fi = floor(u), fj = floor(v), t, s;
    long i, j, j1;
    if (fi > (double)n0 - 2.0) { i = n0 - 2; t = 1.0; } else if (fi >= 0.0) { i = (long)fi; t = u - fi; } else { i = 0; t = 0.0; }
    s = v - fj;
    j = (long)fj;
    if (M(LAYOUT_IS_RING)) {
        j = ((j % n1) + n1) % n1;  /* the angle wraps: column n1-1 neighbours column 0 */
        j1 = (j + 1) % n1;
    } else if (fj > (double)n1 - 2.0) { j = n1 - 2; j1 = n1 - 1; s = 1.0; }
    else if (fj >= 0.0) { j1 = j + 1; }
    else { j = 0; j1 = 1; s = 0.0; }
    return (1.0 - t) * (1.0 - s) * cell(i, j) + t * (1.0 - s) * cell(i + 1, j)
         + t * s * cell(i + 1, j1) + (1.0 - t) * s * cell(i, j1);
}

int main(void)
{
    double q[2], w;
    while (fread(q, sizeof(double), 2, stdin) == 2) {
        w = lookup(q[0], q[1]);
        fwrite(&w, sizeof(double), 1, stdout);
    }
    return 0;
}

#else

#define AXES 5
static const char AXIS_NAMES[AXES + 1] = "CXYZW";

/* a program's points: every axis's position and velocity (per second) at each, the time into
 * it [s] (0 at a cut's first point), and whether it starts a cut */
typedef struct {
    double *pos[AXES], *vel[AXES], *t;
    int *start;
    long n, cap;
    int spline, mask;
} Program;

static void *grown(void *block, size_t bytes)
{
    void *p = realloc(block, bytes);
    if (!p) { fputs("ftsref: out of memory\n", stderr); exit(2); }
    return p;
}

static void push(Program *p, const double *pos, const double *vel, double t, int start)
{
    int a;
    if (p->n == p->cap) {
        p->cap = p->cap ? 2 * p->cap : 1024;
        for (a = 0; a < AXES; a++) {
            p->pos[a] = grown(p->pos[a], (size_t)p->cap * sizeof(double));
            p->vel[a] = grown(p->vel[a], (size_t)p->cap * sizeof(double));
        }
        p->t = grown(p->t, (size_t)p->cap * sizeof(double));
        p->start = grown(p->start, (size_t)p->cap * sizeof(int));
    }
    for (a = 0; a < AXES; a++) { p->pos[a][p->n] = pos[a]; p->vel[a][p->n] = vel[a]; }
    p->t[p->n] = t;
    p->start[p->n] = start;
    p->n++;
}

typedef struct {
    double pos[AXES], vel[AXES], word[AXES], speed[AXES], seconds, ta, feed, ix90, prev_c;
    int given[AXES], has_speed[AXES], inc, pmac_cut, g93, motion, cutting, g93_seconds, wraps, power, i42;
    int dwell, g52, ended;
    double offset[AXES];
} Reader;

/* a decimal number as controllers write it: sign, digits, point, digits (strtod alone would
 * read "0X1" as hexadecimal, and PMAC words follow each other without spaces) */
static double number(const char *s, const char **end)
{
    char text[64];
    size_t n = 0;
    if (s[n] == '-' || s[n] == '+') n++;
    while (n < sizeof text - 1 && (isdigit((unsigned char)s[n]) || s[n] == '.')) n++;
    memcpy(text, s, n);
    text[n] = '\0';
    *end = s + n;
    if (n == 0 || (n == 1 && (s[0] == '-' || s[0] == '+' || s[0] == '.'))) { *end = s; return 0.0; }
    return strtod(text, NULL);
}

static int axis_of(char c)
{
    const char *at = strchr(AXIS_NAMES, c);
    return (c && at) ? (int)(at - AXIS_NAMES) : -1;
}

/* one keyword or word of a line whose comments are removed; returns the characters used */
static size_t token(Reader *r, Program *p, const char *s)
{
    const char *end;
    double v;
    int a = axis_of(s[0]);
    if (strncmp(s, "RAPID", 5) == 0 || strncmp(s, "LINEAR", 6) == 0) { r->seconds = 0.0; return s[0] == 'R' ? 5 : 6; }
    if (strncmp(s, "ABS", 3) == 0 || strncmp(s, "INC", 3) == 0) { r->inc = s[0] == 'I'; return 3; }
    if (strncmp(s, "SPLINE", 6) == 0) {  /* Turbo: SPLINE1, its time TM (I42=0) or TA (I42=1); Power: spline<ms> */
        v = number(s + 6, &end);
        p->spline = 1;
        if (r->power) r->ta = v / 1000.0;
        r->seconds = r->ta;
        return (size_t)(end - s);
    }
    if (strncmp(s, "PVT", 3) == 0) { r->seconds = number(s + 3, &end) / 1000.0; p->spline = 0; return (size_t)(end - s); }
    if (s[0] == 'T' && (s[1] == 'A' || s[1] == 'S' || s[1] == 'M')) {
        v = number(s + 2, &end);
        /* Turbo PMAC I42: TM (0) or TA (1) is the SPLINE and PVT move time; PVT<ms> sets it too */
        if ((s[1] == 'M' && !r->i42) || (s[1] == 'A' && r->i42)) { r->ta = v / 1000.0; if (r->seconds > 0.0 || p->spline) r->seconds = r->ta; }
        return (size_t)(end - s);
    }
    v = number(s + 1, &end);
    if (end == s + 1) return 0;
    if (a >= 0) {
        r->word[a] = v;
        r->given[a] = 1;
        if (*end == ':') {
            r->speed[a] = number(end + 1, &end) * 1000.0 / r->ix90;
            r->has_speed[a] = 1;
        }
    } else if (s[0] == 'G') {
        if (v == 93.0 || v == 94.0) r->g93 = v == 93.0;
        if (v == 0.0 || v == 1.0) r->motion = (int)v;
        if (v == 90.0 || v == 91.0) r->inc = v == 91.0;
        if (v == 4.0) r->dwell = 1;
        if (v == 52.0) r->g52 = 1;
    } else if (s[0] == 'M') {
        if (v == 2.0 || v == 30.0) r->ended = 1;
    } else if (s[0] == 'F') {
        r->feed = v;
    }
    return (size_t)(end - s);
}

/* the block's axis words applied: ABS or INC, C modulo 360 the shorter way round */
static void move(Reader *r, Program *p)
{
    int a;
    for (a = 0; a < AXES; a++) {
        double target;
        if (!r->given[a]) continue;
        target = r->inc ? r->pos[a] + r->word[a] : r->word[a] + r->offset[a];
        if (a == 0 && r->wraps && !isnan(r->prev_c)) {
            double step = fmod(target - r->prev_c, 360.0);
            if (step < 0.0) step += 360.0;
            if (step > 180.0) step -= 360.0;
            r->prev_c = target;
            target = r->pos[0] + step;
        } else if (a == 0) {
            r->prev_c = target;
        }
        r->pos[a] = target;
        p->mask |= 1 << a;
        if (r->has_speed[a]) r->vel[a] = r->speed[a];
    }
}

static void block(Reader *r, Program *p, const char *line)
{
    int a, any = 0;
    double rest[AXES] = {0.0, 0.0, 0.0, 0.0, 0.0};
    size_t used;
    for (a = 0; a < AXES; a++) { r->given[a] = 0; r->has_speed[a] = 0; }
    r->dwell = r->g52 = 0;
    while (*line) {
        if (*line == ' ' || *line == '\t' || *line == '\r' || *line == '\n') { line++; continue; }
        used = token(r, p, line);
        if (used == 0) { line++; continue; }  /* a keyword the path does not depend on */
        line += used;
    }
    if (r->dwell) return;  /* G04: its X, U or P is a time, the tool stands */
    if (r->g52) {  /* a local offset added to the positions programmed after it */
        for (a = 0; a < AXES; a++) any |= r->given[a];
        for (a = 0; a < AXES; a++) if (r->given[a] || !any) r->offset[a] = r->given[a] ? r->word[a] : 0.0;
        return;
    }
    for (a = 0; a < AXES; a++) any |= r->given[a];
    if (!any) return;
    if (r->seconds > 0.0) {  /* a PMAC PVT or SPLINE1 move: the cut starts at rest after RAPID */
        if (!r->pmac_cut) { push(p, r->pos, rest, 0.0, 1); r->pmac_cut = 1; }
        move(r, p);
        push(p, r->pos, r->vel, r->seconds, 0);
        return;
    }
    if (r->g93 && r->motion == 1) {
        double t = r->g93_seconds ? r->feed : 60.0 / r->feed, before[AXES];
        int moved = 0, turned;
        /* C printed modulo 360 gives each cut its angle, not the revolutions turned before it */
        if (!r->cutting && r->wraps && !isnan(r->prev_c)) r->pos[0] = r->prev_c;
        for (a = 0; a < AXES; a++) before[a] = r->pos[a];
        move(r, p);
        for (a = 0; a < AXES; a++) moved |= (r->pos[a] != before[a]) << a;
        turned = moved & 1;
        if (!moved) return;  /* a block that moves no axis: the tool stands for its time */
        if (!turned) { r->cutting = 0; return; }  /* C still: an approach or a return, not a cut */
        if (!r->cutting) { push(p, before, rest, 0.0, 1); r->cutting = 1; }
        push(p, r->pos, rest, t, 0);
        return;
    }
    r->cutting = 0;
    move(r, p);
}

static void strip_comments(char *line)
{
    char *out = line, *in = line;
    int depth = 0;
    for (; *in; in++) {
        if (*in == ';') break;
        if (*in == '(') { depth++; continue; }
        if (*in == ')') { if (depth) depth--; continue; }
        if (!depth) *out++ = *in;
    }
    *out = '\0';
}

/* a statement the reference does not read (its documented limits), or NULL */
static const char *unread(const char *line)
{
    const char *c = line;
    while (*c == ' ' || *c == '\t') c++;
    if (*c == '/') return "a block-delete block (/): whether it runs depends on a switch";
    if (strchr(line, '#') || strstr(line, "WHILE") || strstr(line, "IF") || strstr(line, "GOTO")
        || strstr(line, "END"))
        return "a macro statement (#, WHILE, IF, GOTO): the reference reads macro-free programs";
    return NULL;
}

/* 1: read; 0: no cut; -1: refused (the line named on stderr) */
static int read_program(const char *path, Program *p, Reader *r)
{
    char line[1024];
    long number = 0;
    const char *why;
    FILE *f = fopen(path, "r");
    if (!f) { perror(path); return -1; }
    while (!r->ended && fgets(line, sizeof line, f)) {
        char *c;
        number++;
        strip_comments(line);
        for (c = line; *c; c++) *c = (char)toupper((unsigned char)*c);  /* PMAC reads either case */
        if (strncmp(line, "OPEN", 4) == 0 || strncmp(line, "CLOSE", 5) == 0) continue;
        if (!r->seconds && (why = unread(line)) != NULL) {
            fprintf(stderr, "ftsref: line %ld: %s\n", number, why);
            fclose(f);
            return -1;
        }
        block(r, p, line);
    }
    fclose(f);
    return p->n >= 2;
}

/* the manual's PVT cubic in time through (p0, v0) at 0 and (p1, v1) at T, at t = uT */
static double pvt(double p0, double p1, double v0, double v1, double T, double u)
{
    double t = u * T, slope = (p1 - p0) / T;
    double c2 = (3.0 * slope - 2.0 * v0 - v1) / T, c3 = (v0 + v1 - 2.0 * slope) / (T * T);
    return p0 + v0 * t + c2 * t * t + c3 * t * t * t;
}

/* control point m of the cut [lo, hi) of one axis as the controller sequences it: the
 * manual's added pieces (a zero-distance segment of TA at each end) repeat the first and the
 * last point, so the spline leaves and reaches them at rest */
static double ctrl(const double *y, long lo, long hi, long m)
{
    long k = lo + m - 2;
    return y[k < lo ? lo : (k >= hi ? hi - 1 : k)];
}

/* segment j (0 .. hi - lo) of the cut: the uniform cubic B-spline's basis functions */
static double spline(const double *y, long lo, long hi, long j, double u)
{
    double w = 1.0 - u;
    return (w * w * w * ctrl(y, lo, hi, j) + (3.0 * u * u * u - 6.0 * u * u + 4.0) * ctrl(y, lo, hi, j + 1)
            + (-3.0 * u * u * u + 3.0 * u * u + 3.0 * u + 1.0) * ctrl(y, lo, hi, j + 2)
            + u * u * u * ctrl(y, lo, hi, j + 3)) / 6.0;
}

static double sample(const Program *p, int a, long lo, long hi, long k, double u)
{
    const double *y = p->pos[a];
    if (p->spline) return spline(y, lo, hi, k, u);
    return pvt(y[k], y[k + 1], p->vel[a][k], p->vel[a][k + 1], p->t[k + 1], u);
}

int main(int argc, char **argv)
{
    Program p;
    Reader r;
    long k, j, m, lo, hi;
    int a, linear;
    double value;
    memset(&p, 0, sizeof p);
    memset(&r, 0, sizeof r);
    if (argc < 7 || argc > 9 || (m = atol(argv[2])) < 1) {
        fputs("usage: ftsref PROGRAM SAMPLES_PER_SEGMENT IX90_MS G93_SECONDS C_WRAPS POWER_PMAC [I42 [POWER_ON]]\n",
              stderr);
        return 2;
    }
    r.ix90 = strtod(argv[3], NULL);
    r.g93_seconds = atoi(argv[4]);
    r.wraps = atoi(argv[5]);
    r.power = atoi(argv[6]);
    r.i42 = argc >= 8 ? atoi(argv[7]) : 0;
    r.prev_c = NAN;
    r.motion = -1;
    for (a = 0; a < AXES; a++) r.pos[a] = NAN;
    if (argc == 9) {  /* the profile's power-on modes: a block of G words before the file */
        char modes[128];
        snprintf(modes, sizeof modes, "%s", argv[8]);
        block(&r, &p, modes);
    }
    switch (read_program(argv[1], &p, &r)) {
    case -1: return 1;
    case 0: fputs("ftsref: no cut in the program\n", stderr); return 1;
    default: break;
    }
    linear = !r.pmac_cut;
    value = (double)p.mask;
    fwrite(&value, sizeof(double), 1, stdout);
    for (lo = 0; lo < p.n; lo = hi) {
        long segments;
        for (hi = lo + 1; hi < p.n && !p.start[hi]; hi++) {}
        segments = p.spline ? hi - lo + 1 : hi - lo - 1;
        for (k = 0; k < segments; k++)
            for (j = 0; j < m; j++) {
                double u = ((double)j + 0.5) / (double)m;
                for (a = 0; a < AXES; a++) {
                    if (!(p.mask & (1 << a))) continue;
                    if (linear) value = p.pos[a][lo + k] + u * (p.pos[a][lo + k + 1] - p.pos[a][lo + k]);
                    else value = sample(&p, a, lo, hi, p.spline ? k : lo + k, u);
                    fwrite(&value, sizeof(double), 1, stdout);
                }
            }
    }
    return 0;
}
#endif
