// dv_mat_eig_real: eigenvalues of general real matrices against closed forms (a companion
// matrix with known roots, rotation-scaling blocks under a similarity, a defective Jordan
// block, triangular), and bad input. The Eigen cross-check is in tests/xcheck.
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include "dv_test_util.h"
#include "dynval/dv_mat.h"

enum { NMAX = 12 };

static dv_real_t work[DV_MAT_EIGR_WORK_LEN(NMAX)];

// Largest distance from each wanted eigenvalue (re, im) to the nearest computed one not yet
// used, relative to max(1, |wanted|).
static double match(size_t n, const dv_real_t *wr, const dv_real_t *wi, const double *re,
                    const double *im)
{
    int used[NMAX] = {0};
    double worst = 0;
    for (size_t i = 0; i < n; i++) {
        size_t best = n;
        double bd = INFINITY;
        for (size_t k = 0; k < n; k++) {
            const double d = hypot((double)wr[k] - re[i], (double)wi[k] - im[i]);
            if (!used[k] && d < bd) {
                bd = d;
                best = k;
            }
        }
        assert_true(best < n);
        used[best] = 1;
        worst = fmax(worst, bd / fmax(1.0, hypot(re[i], im[i])));
    }
    return worst;
}

static void eig(size_t n, dv_real_t *a, dv_real_t *wr, dv_real_t *wi)
{
    dv_mat_t m = {(uint16_t)n, (uint16_t)n, a};
    assert_int_equal(dv_mat_eig_real(&m, wr, wi, work, DV_MAT_EIGR_WORK_LEN(n)), DV_OK);
    for (size_t i = 0; i < n; i++) {
        if (wi[i] > 0) { // a pair: positive imaginary part first, then its conjugate
            assert_true(i + 1 < n);
            assert_true(wr[i + 1] == wr[i] && wi[i + 1] == -wi[i]);
            i++;
        }
    }
}

// Companion matrix of (x - 1)(x - 2)(x - 3)(x + 4)(x^2 + 2x + 5): roots 1, 2, 3, -4, -1 +- 2i.
static void test_eig_real_companion_roots(void **state)
{
    (void)state;
    // coefficients of x^6 + c5 x^5 + ... + c0, from the roots
    double p[7] = {1, 0, 0, 0, 0, 0, 0}; // p[k]: coefficient of x^k, built up by products
    const double lin[4] = {-1, -2, -3, 4};
    size_t deg = 0;
    for (int r = 0; r < 4; r++) { // multiply by (x + lin[r])
        for (size_t k = deg + 1; k > 0; k--) p[k] = p[k - 1] + lin[r] * p[k];
        p[0] *= lin[r];
        deg++;
    }
    const double q[3] = {5, 2, 1}; // x^2 + 2x + 5
    double t[7] = {0};
    for (size_t k = 0; k <= deg; k++)
        for (size_t j = 0; j < 3; j++) t[k + j] += p[k] * q[j];
    const size_t n = 6;
    dv_real_t a[36] = {0}, wr[6], wi[6];
    for (size_t i = 1; i < n; i++) a[i * n + i - 1] = 1; // subdiagonal ones
    for (size_t i = 0; i < n; i++) a[i * n + n - 1] = (dv_real_t)(-t[i]); // last column
    eig(n, a, wr, wi);
    const double re[6] = {1, 2, 3, -4, -1, -1}, im[6] = {0, 0, 0, 0, 2, -2};
    const double e = match(n, wr, wi, re, im);
    fprintf(stderr, "companion of a degree-6 polynomial: max relative root error %.3g\n", e);
    assert_true(e <= (sizeof(dv_real_t) == 8 ? 1e-12 : 2e-4));
}

// Three rotation-scaling blocks r (cos t, +-sin t) and two real eigenvalues, mixed by a
// similarity S (unit lower triangular times a permutation-free upper one: well conditioned).
// Like a discretised, lightly damped structure: eigenvalues near the unit circle.
static void test_eig_real_rotation_blocks_under_similarity(void **state)
{
    (void)state;
    const size_t n = 8;
    const double r[3] = {0.999, 0.98, 0.9}, th[3] = {0.05, 0.3, 1.2};
    double d[64] = {0}, s[64] = {0}, si[64] = {0}, tmp[64], a[64];
    for (int b = 0; b < 3; b++) {
        const size_t i = 2u * (size_t)b;
        d[i * n + i] = d[(i + 1) * n + i + 1] = r[b] * cos(th[b]);
        d[i * n + i + 1] = r[b] * sin(th[b]);
        d[(i + 1) * n + i] = -r[b] * sin(th[b]);
    }
    d[6 * n + 6] = 0.5;
    d[7 * n + 7] = -0.25;
    // S = L U with L unit lower, U unit upper (entries 0.3 * pattern); S^-1 by solving
    for (size_t i = 0; i < n; i++)
        for (size_t j = 0; j < n; j++) {
            double sum = 0;
            for (size_t k = 0; k < n; k++) {
                const double l = k == i ? 1 : (k < i ? 0.3 * sin((double)(i * 7 + k)) : 0);
                const double u = k == j ? 1 : (k < j ? 0.3 * cos((double)(k * 5 + j)) : 0);
                sum += l * u;
            }
            s[i * n + j] = sum;
        }
    { // S^-1 by Gauss-Jordan (test-side, double)
        double m[64], inv[64];
        memcpy(m, s, sizeof m);
        for (size_t i = 0; i < 64; i++) inv[i] = (i / n == i % n) ? 1 : 0;
        for (size_t c = 0; c < n; c++) {
            const double pv = m[c * n + c];
            for (size_t j = 0; j < n; j++) {
                m[c * n + j] /= pv;
                inv[c * n + j] /= pv;
            }
            for (size_t i = 0; i < n; i++) {
                if (i == c) continue;
                const double f = m[i * n + c];
                for (size_t j = 0; j < n; j++) {
                    m[i * n + j] -= f * m[c * n + j];
                    inv[i * n + j] -= f * inv[c * n + j];
                }
            }
        }
        memcpy(si, inv, sizeof si);
    }
    for (size_t i = 0; i < n; i++)
        for (size_t j = 0; j < n; j++) {
            double sum = 0;
            for (size_t k = 0; k < n; k++) sum += s[i * n + k] * d[k * n + j];
            tmp[i * n + j] = sum;
        }
    dv_real_t ar[64], wr[8], wi[8];
    for (size_t i = 0; i < n; i++)
        for (size_t j = 0; j < n; j++) {
            double sum = 0;
            for (size_t k = 0; k < n; k++) sum += tmp[i * n + k] * si[k * n + j];
            a[i * n + j] = sum;
            ar[i * n + j] = (dv_real_t)sum;
        }
    eig(n, ar, wr, wi);
    double re[8], im[8];
    for (int b = 0; b < 3; b++) {
        re[2 * b] = re[2 * b + 1] = r[b] * cos(th[b]);
        im[2 * b] = r[b] * sin(th[b]);
        im[2 * b + 1] = -im[2 * b];
    }
    re[6] = 0.5;
    re[7] = -0.25;
    im[6] = im[7] = 0;
    const double e = match(n, wr, wi, re, im);
    fprintf(stderr, "rotation blocks under a similarity: max relative error %.3g\n", e);
    assert_true(e <= (sizeof(dv_real_t) == 8 ? 1e-12 : 1e-4));
    (void)a;
}

// Triangular input (already converged: no iteration) and a defective 2 x 2 Jordan block
// (eigenvalue 0.7 twice; only sqrt(eps) accuracy is possible there).
static void test_eig_real_triangular_and_jordan(void **state)
{
    (void)state;
    dv_real_t t[9] = {3, 1, 4, 0, -2, 5, 0, 0, 0.5}, wr[3], wi[3];
    eig(3, t, wr, wi);
    const double re3[3] = {3, -2, 0.5}, im3[3] = {0, 0, 0};
    assert_true(match(3, wr, wi, re3, im3) <= (sizeof(dv_real_t) == 8 ? 1e-14 : 1e-6));
    // A = S J S^-1, J = [[0.7, 1], [0, 0.7]], S = [[1, 0.5], [0.25, 1]] (det 0.875)
    const double sj[4] = {1, 0.5, 0.25, 1}, jj[4] = {0.7, 1, 0, 0.7};
    const double sinv[4] = {1 / 0.875, -0.5 / 0.875, -0.25 / 0.875, 1 / 0.875};
    dv_real_t j[4], jr[2], ji[2];
    for (int r = 0; r < 2; r++)
        for (int c = 0; c < 2; c++) {
            double sum = 0;
            for (int k = 0; k < 2; k++)
                for (int l = 0; l < 2; l++) sum += sj[r * 2 + k] * jj[k * 2 + l] * sinv[l * 2 + c];
            j[r * 2 + c] = (dv_real_t)sum;
        }
    eig(2, j, jr, ji);
    const double rej[2] = {0.7, 0.7}, imj[2] = {0, 0};
    const double e = match(2, jr, ji, rej, imj);
    fprintf(stderr, "Jordan block: error %.3g\n", e);
    assert_true(e <= (sizeof(dv_real_t) == 8 ? 1e-7 : 3e-3));
    dv_real_t one = (dv_real_t)-3.5, w1r, w1i;
    eig(1, &one, &w1r, &w1i);
    assert_true(w1r == (dv_real_t)-3.5 && w1i == 0);
}

static void test_eig_real_bad_input(void **state)
{
    (void)state;
    dv_real_t a[6] = {1, 2, 3, 4, 5, 6}, wr[3], wi[3];
    dv_mat_t rect = {2, 3, a};
    assert_int_equal(dv_mat_eig_real(&rect, wr, wi, work, 100), DV_EINVAL);
    dv_mat_t sq = {2, 2, a};
    assert_int_equal(dv_mat_eig_real(&sq, NULL, wi, work, 100), DV_EINVAL);
    assert_int_equal(dv_mat_eig_real(&sq, wr, wi, NULL, 100), DV_EINVAL);
    assert_int_equal(dv_mat_eig_real(&sq, wr, wi, work, DV_MAT_EIGR_WORK_LEN(2) - 1), DV_ESIZE);
    a[3] = (dv_real_t)NAN;
    assert_int_equal(dv_mat_eig_real(&sq, wr, wi, work, 100), DV_ENUMERIC);
    a[3] = (dv_real_t)INFINITY;
    assert_int_equal(dv_mat_eig_real(&sq, wr, wi, work, 100), DV_ENUMERIC);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_eig_real_companion_roots),
        cmocka_unit_test(test_eig_real_rotation_blocks_under_similarity),
        cmocka_unit_test(test_eig_real_triangular_and_jordan),
        cmocka_unit_test(test_eig_real_bad_input),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
