/* The offline per-sample loops of two estimators (guardid/estimators), a whole log per
 * call: the arithmetic of their Python paths sample after sample (the same estimates to
 * round-off: tests/test_estimators_native.py).
 *
 * guardid_hopfield_samples: Hopfield.update's n_out = 2 fast path (hopfield.py): the
 * linearly implicit step in s with the 2 x 2 solve by Cramer's rule, the
 * fraction-to-boundary rule (_boundary_step) and the clip to +-smax.
 * guardid_gradient_samples: Gradient.fit's loop, theta += gAT_k (y_k - A_k theta), with
 * its divergence check every `check` samples; also Hopfield.fit's explicit Euler loop.
 * guardid_mlp_epoch: one epoch of MLP.fit's mini-batch gradient descent.
 *
 * Layout (C order, float64): A (N, n, p) the samples' regressors, y (N, n) the outputs,
 * hist (N / every, p) the state after every `every`-th sample.
 * C99, no dynamic allocation: the caller passes the work arrays (sizes below).
 */
#include <math.h>

#define TAU 0.9 /* fraction-to-boundary: a step covers at most 90 % of the distance */
#define VSAFE2 ((0.5 * TAU) * (0.5 * TAU)) /* |v|^2 below this: no boundary cut */

/* s <- s + alpha ds, alpha <= 1 the largest keeping each component within TAU of its
 * distance to the face it moves to, then clipped to +-smax (NaN kept, as numpy's). ds is
 * overwritten. */
static void boundary_step(int p, double *s, double *ds, double smax)
{
    int j;
    int nan = 0;
    double frac = 0.0; /* the largest share of the distance covered (NaN: no cut) */
    for (j = 0; j < p; j++) {
        double sg = ds[j] > 0.0 ? 1.0 : (ds[j] < 0.0 ? -1.0 : ds[j]); /* np.sign */
        double r = fabs(ds[j]) / (1.0 - s[j] * sg);
        if (r != r)
            nan = 1;
        else if (r > frac)
            frac = r;
    }
    if (!nan && frac > TAU) {
        double scale = TAU / frac;
        for (j = 0; j < p; j++)
            ds[j] *= scale;
    }
    for (j = 0; j < p; j++) {
        double v = s[j] + ds[j];
        if (v > smax)
            v = smax;
        if (v < -smax)
            v = -smax;
        s[j] = v;
    }
}

/* D = 1 - s^2, Dd = S^2 D, theta = c + S s. */
static void hopfield_state(int p, const double *s, const double *S, const double *c,
                           double *D, double *Dd, double *theta)
{
    int j;
    for (j = 0; j < p; j++) {
        D[j] = 1.0 - s[j] * s[j];
        Dd[j] = (S[j] * S[j]) * D[j];
        theta[j] = c[j] + S[j] * s[j];
    }
}

/* The Hopfield network over N samples of two outputs from the state s (p,) (updated in
 * place): S, c (p,) the box's half-widths and centre, inv_c = beta / dt, smax the largest
 * double below 1. work: 4 p doubles. */
void guardid_hopfield_samples(int N, int p, const double *A, const double *y,
                              const double *S, const double *c, double inv_c, double smax,
                              int every, double *s, double *hist, double *work)
{
    double *D = work, *Dd = work + p, *theta = work + 2 * p, *v = work + 3 * p;
    double b = 0.0; /* an upper bound on max |s_j| */
    int j, k, h = 0;
    for (j = 0; j < p; j++)
        b = fabs(s[j]) > b ? fabs(s[j]) : b;
    hopfield_state(p, s, S, c, D, Dd, theta);
    for (k = 0; k < N; k++) {
        const double *a0 = A + (long)k * 2 * p, *a1 = a0 + p;
        double q00 = 0.0, q01 = 0.0, q11 = 0.0, at0 = 0.0, at1 = 0.0, nv = 0.0;
        double det, e0, e1, w0, w1;
        for (j = 0; j < p; j++) {
            q00 += a0[j] * (a0[j] * Dd[j]);
            q01 += a0[j] * (a1[j] * Dd[j]);
            q11 += a1[j] * (a1[j] * Dd[j]);
            at0 += a0[j] * theta[j];
            at1 += a1[j] * theta[j];
        }
        det = q00 * q11 - q01 * q01;
        if (0.0 > det)
            det = 0.0;
        det = det + (q00 + q11) * inv_c + inv_c * inv_c;
        e0 = y[2 * k] - at0;
        e1 = y[2 * k + 1] - at1;
        w0 = ((q11 + inv_c) * e0 - q01 * e1) / det;
        w1 = ((q00 + inv_c) * e1 - q01 * e0) / det;
        for (j = 0; j < p; j++) {
            v[j] = (w0 * a0[j] + w1 * a1[j]) * S[j];
            nv += v[j] * v[j];
        }
        if (nv < VSAFE2) { /* |ds_j| < TAU (1 - |s_j|): no cut; b bounds max |s_j| */
            for (j = 0; j < p; j++)
                s[j] = s[j] + D[j] * v[j];
            b = (b + sqrt(nv)) * (1.0 + 1e-12);
            if (b >= 1.0) {
                b = 0.0;
                for (j = 0; j < p; j++)
                    b = fabs(s[j]) > b ? fabs(s[j]) : b;
                if (b >= 1.0) {
                    for (j = 0; j < p; j++)
                        s[j] = s[j] > smax ? smax : (s[j] < -smax ? -smax : s[j]);
                    b = smax;
                }
            }
        } else {
            for (j = 0; j < p; j++)
                v[j] = D[j] * v[j];
            boundary_step(p, s, v, smax);
            b = 1.0;
        }
        hopfield_state(p, s, S, c, D, Dd, theta);
        if ((k + 1) % every == 0) {
            for (j = 0; j < p; j++)
                hist[(long)h * p + j] = s[j];
            h++;
        }
    }
}

/* theta (p,) <- theta + gAT_k (y_k - A_k theta) over the N samples, gAT (N, p, n) the
 * per-sample gains; with hop_gain > 0 instead theta <- theta + hop_gain (1 - theta^2)
 * gAT_k (y_k - A_k theta) (the Hopfield network's explicit Euler step in s, with A = A S,
 * y = y - A c, gAT = S A^T). Every `check` samples the run stops when max |theta_j| is not
 * below blowup (NaN included). Returns the samples done. work: n doubles. */
int guardid_gradient_samples(int N, int n, int p, const double *A, const double *y,
                             const double *gAT, int every, int check, double blowup,
                             double hop_gain, double *theta, double *hist, double *work)
{
    int i, j, k, h = 0;
    for (i = 0; i < N; i++) {
        const double *a = A + (long)i * n * p, *g = gAT + (long)i * p * n;
        for (j = 0; j < n; j++) {
            double at = 0.0;
            for (k = 0; k < p; k++)
                at += a[j * p + k] * theta[k];
            work[j] = y[(long)i * n + j] - at;
        }
        for (k = 0; k < p; k++) {
            double d = 0.0;
            for (j = 0; j < n; j++)
                d += g[k * n + j] * work[j];
            if (hop_gain > 0.0)
                theta[k] = theta[k] + hop_gain * (1.0 - theta[k] * theta[k]) * d;
            else
                theta[k] = theta[k] + d;
        }
        if ((i + 1) % every == 0) {
            for (k = 0; k < p; k++)
                hist[(long)h * p + k] = theta[k];
            h++;
        }
        if ((i + 1) % check == 0) {
            for (k = 0; k < p; k++)
                if (!(fabs(theta[k]) < blowup))
                    return i + 1;
        }
    }
    return N;
}

/* One epoch of the MLP's mini-batch gradient descent (mlp.py: MLP._loss_grad, MLP._step):
 * the samples in the order perm (N,), batches of B (the last one shorter). Xn (N, k)
 * normalised inputs, An (N, n, p) normalised regressors, yn (N, n) normalised outputs;
 * weights W1 (k, h), b1 (h,), W2 (h, p), b2 (p,) and their velocities vW1 .. vb2 (used
 * when mu > 0) updated in place, in that order in one array each: w (k h + h + h p + p),
 * vel (same). lr the learning rate, mu the momentum, wd the weight decay on W2.
 * work: 2 B h + B p + n + p + k h + h + h p + p doubles. */
void guardid_mlp_epoch(int N, int B, int k, int h, int n, int p, const double *Xn,
                       const double *An, const double *yn, const long long *perm, double lr,
                       double mu, double wd, double *w, double *vel, double *work)
{
    int nw = k * h + h + h * p + p;
    double *W1 = w, *b1 = w + k * h, *W2 = b1 + h, *b2 = W2 + h * p;
    double *H = work, *dZ = H + (long)B * h, *G = dZ + (long)B * h, *E = G + (long)B * p;
    double *o = E + n, *grad = o + p; /* grad: gW1, gb1, gW2, gb2, the layout of w */
    double *gW1 = grad, *gb1 = grad + k * h, *gW2 = gb1 + h, *gb2 = gW2 + h * p;
    int s, b, i, j, m;
    for (s = 0; s < N; s += B) {
        int nb = N - s < B ? N - s : B;
        for (b = 0; b < nb; b++) { /* forward, the error and dF/do = A^T e / B */
            long r = (long)perm[s + b];
            const double *x = Xn + r * k, *a = An + r * n * p, *yy = yn + r * n;
            double *hb = H + (long)b * h, *g = G + (long)b * p;
            for (j = 0; j < h; j++) {
                double z = 0.0;
                for (i = 0; i < k; i++)
                    z += x[i] * W1[i * h + j];
                hb[j] = tanh(z + b1[j]);
            }
            for (m = 0; m < p; m++) {
                double v = 0.0;
                for (j = 0; j < h; j++)
                    v += hb[j] * W2[j * p + m];
                o[m] = v + b2[m];
            }
            for (i = 0; i < n; i++) {
                double v = 0.0;
                for (m = 0; m < p; m++)
                    v += a[i * p + m] * o[m];
                E[i] = v - yy[i];
            }
            for (m = 0; m < p; m++) {
                double v = 0.0;
                for (i = 0; i < n; i++)
                    v += a[i * p + m] * E[i];
                g[m] = v / nb;
            }
            for (j = 0; j < h; j++) { /* back through tanh */
                double v = 0.0;
                for (m = 0; m < p; m++)
                    v += g[m] * W2[j * p + m];
                dZ[(long)b * h + j] = v * (1.0 - hb[j] * hb[j]);
            }
        }
        for (j = 0; j < nw; j++)
            grad[j] = 0.0;
        for (b = 0; b < nb; b++) {
            const double *x = Xn + (long)perm[s + b] * k, *hb = H + (long)b * h;
            const double *g = G + (long)b * p, *dz = dZ + (long)b * h;
            for (j = 0; j < h; j++)
                for (m = 0; m < p; m++)
                    gW2[j * p + m] += hb[j] * g[m];
            for (m = 0; m < p; m++)
                gb2[m] += g[m];
            for (i = 0; i < k; i++)
                for (j = 0; j < h; j++)
                    gW1[i * h + j] += x[i] * dz[j];
            for (j = 0; j < h; j++)
                gb1[j] += dz[j];
        }
        for (j = 0; j < h * p; j++)
            gW2[j] += wd * W2[j];
        for (j = 0; j < nw; j++) {
            if (mu != 0.0) {
                vel[j] = vel[j] * mu - lr * grad[j];
                w[j] += vel[j];
            } else {
                w[j] -= lr * grad[j];
            }
        }
    }
}
