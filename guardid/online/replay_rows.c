/* The per-row recursions of the online tracker's replay (guardid/online/replay_loop.py),
 * a block of used rows per call: the numpy fast path's arithmetic row after row.
 *
 * Layout (C order, float64): A (L, n, p) the rows' joint equations (absent joints as zero
 * rows), y (L, n) [N m], W (p, p) the information, b (p,) the Hopfield biases, s (p,) the
 * Hopfield state, theta (p,). Outputs per row: the estimate after it (post / states,
 * (L, p)) and the a-priori residuals y - A theta_before (resid, (L, n)).
 *
 * C99, no dynamic allocation: the caller passes the work arrays (sizes below). Returns 0,
 * or k + 1 when the system of row (RLS) or step (Hopfield) k is not positive definite by
 * round-off (the inputs then are partly updated: the caller keeps its own copy and takes
 * its numpy path, whose LU solve handles it).
 */
#include <math.h>

/* The Cholesky factor F of the lower triangle of M (p, p) in place, the reciprocals of its
 * diagonal in inv (p,) (multiplications, not divisions, in the solves); 0 if positive
 * definite. */
static int cholesky(int p, double *M, double *inv)
{
    int i, j, k;
    for (j = 0; j < p; j++) {
        double d = M[j * p + j];
        for (k = 0; k < j; k++)
            d -= M[j * p + k] * M[j * p + k];
        if (!(d > 0.0))
            return 1;
        d = sqrt(d);
        M[j * p + j] = d;
        inv[j] = 1.0 / d;
        for (i = j + 1; i < p; i++) {
            double v = M[i * p + j];
            for (k = 0; k < j; k++)
                v -= M[i * p + k] * M[j * p + k];
            M[i * p + j] = v * inv[j];
        }
    }
    return 0;
}

/* x <- (F F^T)^-1 x with F, inv from cholesky(). */
static void cholesky_solve(int p, const double *F, const double *inv, double *x)
{
    int i, k;
    for (i = 0; i < p; i++) {
        double v = x[i];
        for (k = 0; k < i; k++)
            v -= F[i * p + k] * x[k];
        x[i] = v * inv[i];
    }
    for (i = p - 1; i >= 0; i--) {
        double v = x[i];
        for (k = i + 1; k < p; k++)
            v -= F[k * p + i] * x[k];
        x[i] = v * inv[i];
    }
}

/* resid (n,) = y - a theta for one row a (n, p). */
static void residuals(int n, int p, const double *a, const double *y, const double *theta,
                      double *resid)
{
    int r, i;
    for (r = 0; r < n; r++) {
        double e = y[r];
        for (i = 0; i < p; i++)
            e -= a[r * p + i] * theta[i];
        resid[r] = e;
    }
}

/* W <- lam W + a^T a + diag(f) for one row a (n, p), W symmetric (its lower triangle read,
 * both written); M (p, p), if not null, gets lam W + a^T a (lower triangle). */
static void information_row(int n, int p, const double *a, double lam, const double *f,
                            double *W, double *M)
{
    int i, j, r;
    for (i = 0; i < p; i++) {
        for (j = 0; j <= i; j++) {
            double m = lam * W[i * p + j];
            for (r = 0; r < n; r++)
                m += a[r * p + i] * a[r * p + j];
            if (M)
                M[i * p + j] = m;
            if (i == j)
                m += f[i];
            W[i * p + j] = m;
            W[j * p + i] = m;
        }
    }
}

/* The information alone over L rows: W_k = lam W_(k-1) + A_k^T A_k + diag(f) (W at a row
 * inside a block, after an alarm there). */
void guardid_information_rows(int L, int n, int p, const double *A, double lam,
                              const double *f, double *W)
{
    int k;
    for (k = 0; k < L; k++)
        information_row(n, p, A + (long)k * n * p, lam, f, W, 0);
}

/* RLS in information form over L rows: W_k = lam W_(k-1) + A_k^T A_k + diag(f) and
 * theta_k = theta_(k-1) + (lam W_(k-1) + A_k^T A_k)^-1 A_k^T (y_k - A_k theta_(k-1)).
 * work: p * p + 2 * p doubles. */
int guardid_rls_rows(int L, int n, int p, const double *A, const double *y, double lam,
                     const double *f, double *W, double *theta, double *post, double *resid,
                     double *work)
{
    double *M = work, *x = work + p * p, *inv = x + p;
    int k, i, r;
    for (k = 0; k < L; k++) {
        const double *a = A + (long)k * n * p;
        double *e = resid + (long)k * n;
        residuals(n, p, a, y + (long)k * n, theta, e);
        information_row(n, p, a, lam, f, W, M);
        for (i = 0; i < p; i++) {
            double v = 0.0;
            for (r = 0; r < n; r++)
                v += a[r * p + i] * e[r];
            x[i] = v;
        }
        if (cholesky(p, M, inv))
            return k + 1;
        cholesky_solve(p, M, inv, x);
        for (i = 0; i < p; i++) {
            theta[i] += x[i];
            post[(long)k * p + i] = theta[i];
        }
    }
    return 0;
}

/* The windowed Hopfield network over L rows, rows_per_step (K) rows a step
 * (replay_loop.MethodReplay._hopfield): per step the weights' part
 * Gs = g S mean(W_j) S and D^-1 = 1 / (1 - s0^2) held at the step's start state s0 (the
 * estimate theta0 = c + S s0), each row j with its own force
 * Bt_j = Gs s0 + g S (Bd_j + f phc_j - W_j theta0) (= (Gs - g S W_j S) s0
 * + g S (Bd_j + f phc_j - W_j c)), then per row
 * (Gs + D^-1) s_j = (D^-1 + g S f S) s_(j-1) + lam g S f psi_(j-1) + Bt_j and
 * psi_j = lam psi_(j-1) + S s_(j-1); the fraction-to-boundary rule (tau, smax) on the
 * step. States (L, p) are s after each row; W, b and s are left as after the last row.
 * work: 2 * p * p + K * p + 9 * p + 2 * K doubles. */
int guardid_hopfield_rows(int L, int n, int p, int K, const double *A, const double *y,
                          double lam, const double *f, const double *S, const double *c,
                          double g, double tau, double smax, double *W, double *b, double *s,
                          double *states, double *resid, double *work)
{
    double *Gs = work;                      /* (p, p), lower triangle: then its factor */
    double *Wn = Gs + p * p;                /* (p, p), lower triangle: W after the step */
    double *Bt = Wn + p * p;                /* (K, p) */
    double *Bd = Bt + (long)K * p, *phc = Bd + p, *psi = phc + p, *psi0 = psi + p;
    double *s0 = psi0 + p, *Dinv = s0 + p, *x = Dinv + p, *th0 = x + p;
    double *inv = th0 + p, *wa = inv + p, *wb = wa + K, sa, sb; /* wa, wb (K,) */
    double bound = 0.0;
    int k0, i, j, l, r;
    for (i = 0; i < p; i++) {
        Bd[i] = b[i];
        phc[i] = 0.0;
        psi[i] = 0.0;
        if (fabs(s[i]) > bound)
            bound = fabs(s[i]);
    }
    for (k0 = 0; k0 < L; k0 += K) {
        int cnt = L - k0 < K ? L - k0 : K;
        double step = 0.0;
        for (j = cnt - 1; j >= 0; j--) { /* row j's weight in W_end and in sum W */
            wa[j] = j == cnt - 1 ? 1.0 : lam * wa[j + 1];
            wb[j] = j == cnt - 1 ? 1.0 : 1.0 + lam * wb[j + 1];
        }
        for (j = 0, sa = 0.0, sb = 0.0; j < cnt; j++) {
            sa += wa[j];
            sb += wb[j];
        }
        for (i = 0; i < p; i++) {
            s0[i] = s[i];
            psi0[i] = psi[i];
            Dinv[i] = 1.0 / (1.0 - s[i] * s[i]);
            th0[i] = c[i] + S[i] * s[i];
        }
        for (i = 0; i < p; i++) { /* v = W th0; the sums from W before the step */
            double v = 0.0;
            for (l = 0; l < p; l++)
                v += W[i * p + l] * th0[l];
            x[i] = v;
            for (l = 0; l <= i; l++) {
                Gs[i * p + l] = lam * wb[0] * W[i * p + l];
                Wn[i * p + l] = lam * wa[0] * W[i * p + l];
            }
            Gs[i * p + i] += sb * f[i];
            Wn[i * p + i] += sa * f[i];
        }
        for (j = 0; j < cnt; j++) { /* W_j = lam W_(j-1) + A_j^T A_j + F summed, W_j th0 */
            const double *a = A + (long)(k0 + j) * n * p, *yj = y + (long)(k0 + j) * n;
            double *rj = Bt + (long)j * p;
            for (i = 0; i < p; i++) {
                for (l = 0; l <= i; l++) {
                    double q = 0.0;
                    for (r = 0; r < n; r++)
                        q += a[r * p + i] * a[r * p + l];
                    Gs[i * p + l] += wb[j] * q;
                    Wn[i * p + l] += wa[j] * q;
                }
                x[i] = lam * x[i] + f[i] * th0[i];
            }
            for (r = 0; r < n; r++) {
                double at = 0.0;
                for (l = 0; l < p; l++)
                    at += a[r * p + l] * th0[l];
                for (i = 0; i < p; i++)
                    x[i] += a[r * p + i] * at;
            }
            for (i = 0; i < p; i++) {
                double aty = 0.0;
                for (r = 0; r < n; r++)
                    aty += a[r * p + i] * yj[r];
                Bd[i] = lam * Bd[i] + aty;
                phc[i] = lam * phc[i] + c[i];
                rj[i] = g * S[i] * (Bd[i] + f[i] * phc[i] - x[i]);
            }
        }
        for (i = 0; i < p; i++) {
            for (l = 0; l <= i; l++) {
                W[i * p + l] = Wn[i * p + l];
                W[l * p + i] = Wn[i * p + l];
                Gs[i * p + l] *= g * S[i] * S[l] / cnt;
            }
        }
        for (i = 0; i < p; i++) { /* x = Gs s0, Gs symmetric in its lower triangle */
            double v = 0.0;
            for (l = 0; l <= i; l++)
                v += Gs[i * p + l] * s0[l];
            for (l = i + 1; l < p; l++)
                v += Gs[l * p + i] * s0[l];
            x[i] = v;
        }
        for (j = 0; j < cnt; j++)
            for (i = 0; i < p; i++)
                Bt[(long)j * p + i] += x[i];
        for (i = 0; i < p; i++)
            Gs[i * p + i] += Dinv[i];
        if (cholesky(p, Gs, inv))
            return k0 + 1;
        for (j = 0; j < cnt; j++) {
            const double *prev = j ? states + (long)(k0 + j - 1) * p : s0;
            double *sj = states + (long)(k0 + j) * p, *rj = Bt + (long)j * p;
            for (i = 0; i < p; i++) {
                double gsf = g * S[i] * f[i];
                sj[i] = (Dinv[i] + gsf * S[i]) * prev[i] + lam * gsf * psi[i] + rj[i];
            }
            cholesky_solve(p, Gs, inv, sj);
            for (i = 0; i < p; i++)
                psi[i] = lam * psi[i] + S[i] * prev[i];
        }
        {
            const double *last = states + (long)(k0 + cnt - 1) * p;
            for (i = 0; i < p; i++)
                step += (last[i] - s0[i]) * (last[i] - s0[i]);
            step = sqrt(step);
        }
        if (bound < 0.99 && step < tau * (1.0 - bound)) {
            bound = (bound + step) * (1.0 + 1e-12); /* inside the fraction-to-boundary limit */
        } else { /* the step cut short: the rows' states scaled alike, psi after them */
            const double *last = states + (long)(k0 + cnt - 1) * p;
            double frac = 0.0;
            for (i = 0; i < p; i++) {
                double ds = last[i] - s0[i];
                double room = 1.0 - s0[i] * (ds > 0.0 ? 1.0 : (ds < 0.0 ? -1.0 : 0.0));
                if (fabs(ds) / room > frac)
                    frac = fabs(ds) / room;
            }
            for (j = 0; j < cnt; j++) {
                double *sj = states + (long)(k0 + j) * p;
                for (i = 0; i < p; i++) {
                    double v = sj[i];
                    if (frac > tau)
                        v = (v - s0[i]) * (tau / frac) + s0[i];
                    sj[i] = v < -smax ? -smax : (v > smax ? smax : v);
                }
            }
            for (i = 0; i < p; i++)
                psi[i] = psi0[i];
            for (j = 0; j < cnt; j++) {
                const double *prev = j ? states + (long)(k0 + j - 1) * p : s0;
                for (i = 0; i < p; i++)
                    psi[i] = lam * psi[i] + S[i] * prev[i];
            }
            bound = 0.0;
            for (i = 0; i < p; i++) {
                double v = fabs(states[(long)(k0 + cnt - 1) * p + i]);
                if (v > bound)
                    bound = v;
            }
        }
        for (j = 0; j < cnt; j++) { /* the a-priori residuals: theta = c + S s_(j-1) */
            const double *prev = j ? states + (long)(k0 + j - 1) * p : s0;
            for (i = 0; i < p; i++)
                x[i] = c[i] + S[i] * prev[i];
            residuals(n, p, A + (long)(k0 + j) * n * p, y + (long)(k0 + j) * n, x,
                      resid + (long)(k0 + j) * n);
        }
        for (i = 0; i < p; i++)
            s[i] = states[(long)(k0 + cnt - 1) * p + i];
    }
    for (i = 0; i < p; i++)
        b[i] = Bd[i] + f[i] * (phc[i] + psi[i]);
    return 0;
}

/* The change detector's two-sided CUSUM (online/detector.py ChangeDetector._cusum) over L
 * rows: t (L,) [s], z (L, n) residuals in sigma, ok (L, n) present joint equations; the
 * state g, zero_t, rise_t (2, n) [up, down][joint] advanced in place. Returns the row of
 * the first alarm (the state then as after that row), or -1 (as after the rows). */
int guardid_cusum_rows(int L, int n, const double *t, const double *z,
                       const unsigned char *ok, double kappa, double h, double *g,
                       double *zero_t, double *rise_t)
{
    int k, j, side, fired = 0;
    for (k = 0; k < L; k++) {
        for (j = 0; j < n; j++) {
            if (!ok[(long)k * n + j])
                continue;
            for (side = 0; side < 2; side++) {
                double x = side ? -z[(long)k * n + j] : z[(long)k * n + j];
                double *gs = g + side * n + j;
                int was_zero = *gs <= 0.0;
                double v = (*gs + x) - kappa;
                if (!(v > 0.0))
                    v = 0.0;
                *gs = v;
                if (v <= 0.0)
                    zero_t[side * n + j] = t[k];
                else if (was_zero)
                    rise_t[side * n + j] = t[k];
                if (v > h)
                    fired = 1;
            }
        }
        if (fired)
            return k;
    }
    return -1;
}
