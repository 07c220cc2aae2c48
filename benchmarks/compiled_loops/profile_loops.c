/* The time law's profile loops compiled ahead of time: a prototype, measured in docs/planning.md.
 *
 * A line-by-line C version of flowmc/motion/profile_loops.py at commit de49043 (numba, taken out again:
 * every process paid about 1.1 s of CPU for numba before it saved any). Same arithmetic in the same order;
 * build without fused multiply-adds (-ffp-contract=off) and without -ffast-math, and all 39 plans of
 * benchmarks/plan_hashes.py hash the same. profile_loops.py next to this file loads it through ctypes in
 * place of the numba module; see its docstring for the recipe.
 */
#include <math.h>

/* np.minimum(m, x): the smaller, NaN if either is NaN */
static inline double lesser(double m, double x) { return ((x < m || x != x) && m == m) ? x : m; }

/* The fastest y at the nodes under min(cap, limit) and the up/down budgets: backward, then forward. */
void scan(const double *cap, const double *limit, const double *ds, const double *up, const double *down, long n,
          double *out) {
    double total = 0.0, low = INFINITY;
    out[0] = 0.0;
    for (long i = 0; i < n - 1; i++) {
        total = total + 2.0 * down[i] * ds[i];
        out[i + 1] = total;
    }
    for (long i = n - 1; i >= 0; i--) {
        double c = out[i];
        low = lesser(low, lesser(cap[i], limit[i]) + c);
        out[i] = low - c;
    }
    total = 0.0;
    low = INFINITY;
    for (long i = 0; i < n; i++) {
        if (i > 0) total = total + 2.0 * up[i - 1] * ds[i - 1];
        low = lesser(low, out[i] - total);
        out[i] = low + total;
    }
}

/* The budgets of one round (timelaw._Budgets), axis by axis; level and least are work arrays of n. */
void budgets(const double *cap, const double *faster, const double *slower, int sign, const double *widen,
             const double *alpha, const double *beta_up, const double *beta_down, const double *gamma_up,
             const double *gamma_down, const double *jmax, const double *t_win, const double *k3, const double *p3,
             double window, long rows, long n, double *up, double *down, double *level, double *least) {
    for (long k = 0; k < n; k++) {
        double a = faster[k], b = faster[k + 1];
        level[k] = lesser(cap[k], (a > b || a != a) ? a : b);
        if (sign) least[k] = lesser(cap[k], lesser(slower[k], slower[k + 1]));
        up[k] = INFINITY; down[k] = INFINITY;
    }
    for (long r = 0; r < rows; r++) {
        const double *al = alpha + r * n, *bu = beta_up + r * n, *bd = beta_down + r * n;
        const double *gu = gamma_up + r * n, *gd = gamma_down + r * n;
        if (sign) {
            for (long k = 0; k < n; k++) {
                up[k] = lesser(up[k], al[k] - bu[k] * level[k] + gu[k] * least[k]);
                down[k] = lesser(down[k], al[k] - bd[k] * level[k] + gd[k] * least[k]);
            }
        } else {
            for (long k = 0; k < n; k++) {
                up[k] = lesser(up[k], al[k] - bu[k] * level[k]);
                down[k] = lesser(down[k], al[k] - bd[k] * level[k]);
            }
        }
        if (window > 0) {
            const double *tw = t_win + r * n, *kk = k3 + r * n, *pp = p3 + r * n;
            double jm = jmax[r];
            for (long k = 0; k < n; k++) {
                double y = level[k], root = sqrt(y);
                double coeff = tw[k] * widen[k] + kk[k] * root;
                double jerk = (jm - pp[k] * (y * root)) / coeff;
                jerk = coeff > 0 ? jerk : INFINITY;
                up[k] = lesser(up[k], jerk);
                down[k] = lesser(down[k], jerk);
            }
        }
    }
    for (long k = 0; k < n; k++) {
        double u = up[k], d = down[k];
        u = isfinite(u) ? u : 1e12; d = isfinite(d) ? d : 1e12;
        up[k] = u > 1e-9 ? u : 1e-9;
        down[k] = d > 1e-9 ? d : 1e-9;
    }
}
