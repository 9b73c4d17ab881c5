/* ftsref: what a controller does with ftsweep's files, in plain C99 (docs/controllers.md).
 *
 * Built against a table header (-DFTS_HEADER="file.h" -DFTS_PREFIX=NAME -DFTS_TABLE=name_table):
 *   reads pairs of doubles from stdin -- (rho [um], theta [deg]) for a ring, (x [um], y [um])
 *   for a mesh -- and writes the bilinear lookup (model section 3, eq. 2) of the header's own
 *   table and macros [um] as doubles to stdout.
 * Built without: ftsref PROGRAM M reads a PMAC PVT or SPLINE1 program and writes, for every
 *   segment k and j = 0..M-1, Z [mm] at the segment's parameter u = (j + 0.5)/M: PVT as the
 *   cubic Hermite in time through the end positions and velocities, SPLINE1 as the uniform
 *   cubic B-spline's basis functions over the control points (the ends continued by
 *   P[-1] = 2P[0] - P[1] and P[N] = 2P[N-1] - P[N-2]).
 * Compile with -std=c99 -ffp-contract=off so that no multiply-add is fused.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>

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
    if (fi > n0 - 2.0) { i = n0 - 2; t = 1.0; } else if (fi >= 0.0) { i = (long)fi; t = u - fi; } else { i = 0; t = 0.0; }
    s = v - fj;
    j = (long)fj;
    if (M(LAYOUT_IS_RING)) {
        j = ((j % n1) + n1) % n1;  /* the angle wraps: column n1-1 neighbours column 0 */
        j1 = (j + 1) % n1;
    } else if (fj > n1 - 2.0) { j = n1 - 2; j1 = n1 - 1; s = 1.0; }
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

typedef struct { double *z, *v, *t; long n, cap; int spline; } Program;

static void push(Program *p, double z, double v, double t)
{
    if (p->n == p->cap) {
        p->cap = p->cap ? 2 * p->cap : 1024;
        p->z = realloc(p->z, p->cap * sizeof(double));
        p->v = realloc(p->v, p->cap * sizeof(double));
        p->t = realloc(p->t, p->cap * sizeof(double));
        if (!p->z || !p->v || !p->t) { fputs("ftsref: out of memory\n", stderr); exit(2); }
    }
    p->z[p->n] = z; p->v[p->n] = v; p->t[p->n] = t; p->n++;
}

/* the Z word of a move line ("Zpos" or "Zpos:vel"); 0 when the line has none */
static int z_word(const char *line, double *z, double *v)
{
    const char *at = strchr(line, 'Z');
    char *end;
    if (!at) return 0;
    *z = strtod(at + 1, &end);
    *v = (*end == ':') ? strtod(end + 1, NULL) : 0.0;
    return 1;
}

static int read_program(const char *path, Program *p)
{
    char line[512];
    double z = 0.0, v, seconds = 0.0, last_z = NAN;
    int cutting = 0;
    FILE *f = fopen(path, "r");
    if (!f) { perror(path); return 0; }
    while (fgets(line, sizeof line, f)) {
        if (line[0] == ';' || strncmp(line, "CLOSE", 5) == 0 || strncmp(line, "OPEN", 4) == 0
            || strncmp(line, "ABS", 3) == 0 || strncmp(line, "RAPID", 5) == 0) continue;
        if (strncmp(line, "PVT", 3) == 0) { seconds = strtod(line + 3, NULL) / 1000.0; p->spline = 0; continue; }
        if (strncmp(line, "SPLINE1 TA", 10) == 0) { seconds = strtod(line + 10, NULL) / 1000.0; p->spline = 1; continue; }
        if (!z_word(line, &z, &v)) continue;
        if (seconds == 0.0) { last_z = z; continue; }  /* a RAPID move: the cut starts there, at rest */
        if (!cutting) { push(p, last_z, 0.0, 0.0); cutting = 1; }
        push(p, z, v, seconds);
    }
    fclose(f);
    return p->n >= 2;
}

static double pvt(const Program *p, long k, double u)
{
    double T = p->t[k + 1], d0 = p->v[k] * T, d1 = p->v[k + 1] * T;
    double y0 = p->z[k], y1 = p->z[k + 1];
    double a = 2.0 * (y0 - y1) + d0 + d1, b = 3.0 * (y1 - y0) - 2.0 * d0 - d1;
    return ((a * u + b) * u + d0) * u + y0;
}

static double ctrl(const Program *p, long k)
{
    if (k < 0) return 2.0 * p->z[0] - p->z[1];
    if (k >= p->n) return 2.0 * p->z[p->n - 1] - p->z[p->n - 2];
    return p->z[k];
}

static double spline(const Program *p, long k, double u)
{
    double w = 1.0 - u;
    return (w * w * w * ctrl(p, k - 1) + (3.0 * u * u * u - 6.0 * u * u + 4.0) * ctrl(p, k)
            + (-3.0 * u * u * u + 3.0 * u * u + 3.0 * u + 1.0) * ctrl(p, k + 1) + u * u * u * ctrl(p, k + 2)) / 6.0;
}

int main(int argc, char **argv)
{
    Program p = {0};
    long k, j, m;
    double z;
    if (argc != 3 || (m = atol(argv[2])) < 1) { fputs("usage: ftsref PROGRAM SAMPLES_PER_SEGMENT\n", stderr); return 2; }
    if (!read_program(argv[1], &p)) { fputs("ftsref: no PVT or SPLINE1 cut in the program\n", stderr); return 1; }
    for (k = 0; k + 1 < p.n; k++)
        for (j = 0; j < m; j++) {
            double u = (j + 0.5) / (double)m;
            z = p.spline ? spline(&p, k, u) : pvt(&p, k, u);
            fwrite(&z, sizeof(double), 1, stdout);
        }
    return 0;
}
#endif
