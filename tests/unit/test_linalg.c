/* Unit: linalg — known-answer tests for the shared dense linear algebra. */
#include <float.h>
#include <math.h>
#include <string.h>

#include "numeric/linalg.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

/* A 4x4 orthogonal matrix: Householder reflector I - 2 u u^T / (u^T u). */
static void make_orthogonal4(double q[16])
{
    const double u[4] = {1.0, -2.0, 0.5, 3.0};
    double uu = 0.0;
    for (int i = 0; i < 4; ++i) {
        uu += u[i] * u[i];
    }
    for (int i = 0; i < 4; ++i) {
        for (int j = 0; j < 4; ++j) {
            q[i * 4 + j] = ((i == j) ? 1.0 : 0.0) - 2.0 * u[i] * u[j] / uu;
        }
    }
}

/* A = Q diag(lam) Q^T */
static void make_spd4(const double lam[4], double a[16], double q[16])
{
    make_orthogonal4(q);
    for (int i = 0; i < 4; ++i) {
        for (int j = 0; j < 4; ++j) {
            double s = 0.0;
            for (int k = 0; k < 4; ++k) {
                s += q[i * 4 + k] * lam[k] * q[j * 4 + k];
            }
            a[i * 4 + j] = s;
        }
    }
}

static void test_cholesky_known_factor(void)
{
    /* L = [[2,0,0],[1,3,0],[-1,2,1]] -> A = L L^T */
    const double l_true[9] = {2, 0, 0, 1, 3, 0, -1, 2, 1};
    double a[9];
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_matmul(l_true, (const double[9]){2, 1, -1, 0, 3, 2, 0, 0, 1}, a, 3, 3, 3));
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_cholesky(a, 3));
    for (int i = 0; i < 9; ++i) {
        TEST_ASSERT_DOUBLE_WITHIN(1e-12, l_true[i], a[i]);
    }
    /* det A = (2*3*1)^2 = 36 */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, log(36.0), linalg_cholesky_logdet(a, 3));
}

static void test_solve_and_mahalanobis(void)
{
    const double lam[4] = {5.0, 2.0, 1.0, 0.25};
    double a[16], q[16], l[16];
    make_spd4(lam, a, q);
    memcpy(l, a, sizeof l);
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_cholesky(l, 4));
    const double x_true[4] = {1.0, -1.0, 2.0, 0.5};
    double b[4];
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_matmul(a, x_true, b, 4, 4, 1));
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_cholesky_solve(l, 4, b));
    for (int i = 0; i < 4; ++i) {
        TEST_ASSERT_DOUBLE_WITHIN(1e-12, x_true[i], b[i]);
    }
    /* x along eigenvector k with unit length: MD^2 = 1/lam_k */
    double x[4], zero[4] = {0, 0, 0, 0}, work[4];
    for (int k = 0; k < 4; ++k) {
        for (int i = 0; i < 4; ++i) {
            x[i] = q[i * 4 + k];
        }
        double d2 = -1.0;
        TEST_ASSERT_EQUAL_INT(MD_OK, linalg_mahalanobis2(l, 4, x, zero, work, &d2));
        TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1.0 / lam[k], d2);
    }
    /* logdet = sum log lam */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, log(5.0 * 2.0 * 1.0 * 0.25), linalg_cholesky_logdet(l, 4));
}

static void test_spd_inverse_times_a_is_identity(void)
{
    const double lam[4] = {100.0, 3.0, 0.7, 0.01};
    double a[16], q[16], inv[16], work[16], prod[16], logdet = 0.0;
    make_spd4(lam, a, q);
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_spd_inverse(a, 4, inv, work, &logdet));
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_matmul(inv, a, prod, 4, 4, 4));
    for (int i = 0; i < 4; ++i) {
        for (int j = 0; j < 4; ++j) {
            TEST_ASSERT_DOUBLE_WITHIN(1e-10, (i == j) ? 1.0 : 0.0, prod[i * 4 + j]);
        }
    }
    TEST_ASSERT_DOUBLE_WITHIN(1e-10, log(100.0 * 3.0 * 0.7 * 0.01), logdet);
}

static void test_non_pd_is_reported(void)
{
    const double lam_indef[4] = {2.0, 1.0, -0.5, 1.0};
    double a[16], q[16], inv[16], work[16];
    make_spd4(lam_indef, a, q);
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, linalg_spd_inverse(a, 4, inv, work, NULL));
    /* singular (rank 3) must also fail: pivot is relative to the matrix scale */
    const double lam_sing[4] = {1e6, 1.0, 1.0, 0.0};
    make_spd4(lam_sing, a, q);
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, linalg_cholesky(a, 4));
    /* tiny but well-conditioned matrix is fine: the check is relative */
    const double lam_tiny[4] = {4e-20, 3e-20, 2e-20, 1e-20};
    make_spd4(lam_tiny, a, q);
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_cholesky(a, 4));
    double z[4] = {0, 0, 0, 0};
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, linalg_cholesky(z, 2));
    double nan_m[4] = {1.0, 0.0, 0.0, NAN};
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, linalg_cholesky(nan_m, 2));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_cholesky(a, 0));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_cholesky(NULL, 2));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_cholesky(a, LINALG_MAX_N + 1u));
}

/* A bad argument (a NULL pointer, an order outside 1..LINALG_MAX_N) is an
 * error, never a distance, least of all 0: a perfect match. */
static void test_mahalanobis_reports_bad_arguments(void)
{
    const double l[4] = {2.0, 0.0, 1.0, 3.0};
    const double x[2] = {1.0, 2.0};
    const double m[2] = {0.0, 0.0};
    double work[2];
    double d2 = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_mahalanobis2(NULL, 2, x, m, work, &d2));
    TEST_ASSERT_TRUE(isnan(d2));
    d2 = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_mahalanobis2(l, 2, NULL, m, work, &d2));
    TEST_ASSERT_TRUE(isnan(d2));
    d2 = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_mahalanobis2(l, 2, x, NULL, work, &d2));
    TEST_ASSERT_TRUE(isnan(d2));
    d2 = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_mahalanobis2(l, 2, x, m, NULL, &d2));
    TEST_ASSERT_TRUE(isnan(d2));
    d2 = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_mahalanobis2(l, 0, x, m, work, &d2));
    TEST_ASSERT_TRUE(isnan(d2));
    d2 = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_mahalanobis2(l, LINALG_MAX_N + 1u, x, m, work, &d2));
    TEST_ASSERT_TRUE(isnan(d2));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_mahalanobis2(l, 2, x, m, work, NULL));
    /* the same arguments, valid: (1,2) under L = [[2,0],[1,3]]: y = (0.5, 0.5) */
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_mahalanobis2(l, 2, x, m, work, &d2));
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 0.5, d2);
}

/* Non-finite inputs and unusable factors are numeric failures; a distance
 * beyond the double range between finite points is +inf, not NaN. */
static void test_mahalanobis_nonfinite_and_overflow(void)
{
    const double l[4] = {0.5, 0.0, 0.4, 0.3};
    const double m[2] = {0.0, 0.0};
    double work[2];
    double d2 = 0.0;
    const double nan_x[2] = {NAN, 1.0};
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, linalg_mahalanobis2(l, 2, nan_x, m, work, &d2));
    TEST_ASSERT_TRUE(isnan(d2));
    const double inf_x[2] = {1.0, INFINITY};
    d2 = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, linalg_mahalanobis2(l, 2, inf_x, m, work, &d2));
    TEST_ASSERT_TRUE(isnan(d2));
    const double x[2] = {1.0, 1.0};
    const double zero_pivot[4] = {0.0, 0.0, 0.4, 0.3};
    d2 = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, linalg_mahalanobis2(zero_pivot, 2, x, m, work, &d2));
    TEST_ASSERT_TRUE(isnan(d2));
    const double nan_factor[4] = {0.5, 0.0, NAN, 0.3};
    d2 = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, linalg_mahalanobis2(nan_factor, 2, x, m, work, &d2));
    TEST_ASSERT_TRUE(isnan(d2));
    /* x - m overflows, and the forward solve then computes inf - inf */
    const double far_x[2] = {DBL_MAX, DBL_MAX};
    const double far_m[2] = {-DBL_MAX, -DBL_MAX};
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_mahalanobis2(l, 2, far_x, far_m, work, &d2));
    TEST_ASSERT_TRUE(isinf(d2) && (d2 > 0.0));
}

/* The solve reports misuse and a non-finite solution instead of doing nothing. */
static void test_solve_reports_failures(void)
{
    const double l[4] = {2.0, 0.0, 1.0, 3.0};
    double b[2] = {4.0, 5.0};
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_cholesky_solve(NULL, 2, b));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_cholesky_solve(l, 2, NULL));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_cholesky_solve(l, 0, b));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_cholesky_solve(l, LINALG_MAX_N + 1u, b));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 4.0, b[0]); /* untouched on MD_E_ARG */
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 5.0, b[1]);
    const double zero_pivot[4] = {2.0, 0.0, 1.0, 0.0};
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, linalg_cholesky_solve(zero_pivot, 2, b));
    double nan_b[2] = {NAN, 1.0};
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, linalg_cholesky_solve(l, 2, nan_b));
    /* A = L L^T = [[4, 2], [2, 10]]; A (1, 1) = (6, 12) */
    double ok_b[2] = {6.0, 12.0};
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_cholesky_solve(l, 2, ok_b));
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 1.0, ok_b[0]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 1.0, ok_b[1]);
}

/* log det of a bad argument is NaN, not 0 (det = 1, a plausible value). */
static void test_logdet_reports_bad_arguments(void)
{
    const double l[4] = {2.0, 0.0, 1.0, 3.0};
    TEST_ASSERT_TRUE(isnan(linalg_cholesky_logdet(NULL, 2)));
    TEST_ASSERT_TRUE(isnan(linalg_cholesky_logdet(l, 0)));
    TEST_ASSERT_TRUE(isnan(linalg_cholesky_logdet(l, LINALG_MAX_N + 1u)));
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, log(36.0), linalg_cholesky_logdet(l, 2));
}

static void test_jacobi_recovers_constructed_eigenpairs(void)
{
    const double lam[4] = {0.5, 7.0, -2.0, 3.0}; /* unsorted, one negative */
    const double sorted[4] = {7.0, 3.0, 0.5, -2.0};
    const int src[4] = {1, 3, 0, 2};
    double a[16], q[16], vals[4], vecs[16];
    make_spd4(lam, a, q);
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen(a, 4, vals, vecs, 50));
    for (int k = 0; k < 4; ++k) {
        TEST_ASSERT_DOUBLE_WITHIN(1e-12, sorted[k], vals[k]);
        double dot = 0.0;
        for (int i = 0; i < 4; ++i) {
            dot += vecs[i * 4 + k] * q[i * 4 + src[k]];
        }
        TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1.0, fabs(dot)); /* same column up to sign */
    }
}

static void test_jacobi_larger_matrix_is_orthonormal_decomposition(void)
{
    enum { N = 12 };
    double a[N * N], a0[N * N], vals[N], vecs[N * N];
    for (int i = 0; i < N; ++i) { /* Hilbert-like plus diagonal: symmetric, dense */
        for (int j = 0; j < N; ++j) {
            a[i * N + j] = 1.0 / (double)(i + j + 1) + ((i == j) ? (double)i : 0.0);
        }
    }
    memcpy(a0, a, sizeof a);
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen(a, N, vals, vecs, 30));
    for (int k = 1; k < N; ++k) {
        TEST_ASSERT_TRUE(vals[k - 1] >= vals[k]);
    }
    for (int k = 0; k < N; ++k) { /* A v_k = lam_k v_k and V^T V = I */
        for (int i = 0; i < N; ++i) {
            double av = 0.0;
            for (int j = 0; j < N; ++j) {
                av += a0[i * N + j] * vecs[j * N + k];
            }
            TEST_ASSERT_DOUBLE_WITHIN(1e-11, vals[k] * vecs[i * N + k], av);
        }
        for (int m = 0; m < N; ++m) {
            double d = 0.0;
            for (int i = 0; i < N; ++i) {
                d += vecs[i * N + k] * vecs[i * N + m];
            }
            TEST_ASSERT_DOUBLE_WITHIN(1e-12, (k == m) ? 1.0 : 0.0, d);
        }
    }
}

static void test_jacobi_reports_noconverge_and_bad_input(void)
{
    const double lam[4] = {4.0, 3.0, 2.0, 1.0};
    double a[16], q[16], vals[4], vecs[16];
    make_spd4(lam, a, q);
    TEST_ASSERT_EQUAL_INT(MD_E_NOCONVERGE, linalg_sym_eigen(a, 4, vals, vecs, 1));
    TEST_ASSERT_TRUE(linalg_all_finite(vals, 4));
    make_spd4(lam, a, q);
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_sym_eigen(a, 4, vals, vecs, 0));
    a[5] = INFINITY;
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, linalg_sym_eigen(a, 4, vals, vecs, 10));
    double one = 3.5, v1 = 0.0, e1 = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen(&one, 1, &v1, &e1, 1));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 3.5, v1);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 1.0, e1);
}

static void test_matmul_and_all_finite(void)
{
    const double a[6] = {1, 2, 3, 4, 5, 6};    /* 2x3 */
    const double b[6] = {7, 8, 9, 10, 11, 12}; /* 3x2 */
    double c[4];
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_matmul(a, b, c, 2, 3, 2));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 58.0, c[0]);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 64.0, c[1]);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 139.0, c[2]);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 154.0, c[3]);
    TEST_ASSERT_TRUE(linalg_all_finite(a, 6));
    const double bad[3] = {1.0, NAN, 0.0};
    TEST_ASSERT_FALSE(linalg_all_finite(bad, 3));
    TEST_ASSERT_FALSE(linalg_all_finite(NULL, 3));
    /* A NULL operand is reported and leaves the product untouched. */
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_matmul(NULL, b, c, 2, 3, 2));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_matmul(a, NULL, c, 2, 3, 2));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_matmul(a, b, NULL, 2, 3, 2));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 58.0, c[0]);
}

/* Entries near the ends of the double range: the convergence test must not
 * overflow / underflow into "converged" before any rotation. */
static void test_jacobi_extreme_scales(void)
{
    const double scales[3] = {1e200, 1e-200, 1.0};
    for (size_t k = 0u; k < 3u; ++k) {
        double a[4] = {2.0 * scales[k], 1.0 * scales[k], 1.0 * scales[k], 2.0 * scales[k]};
        double vals[2];
        double vecs[4];
        TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen(a, 2, vals, vecs, 20));
        TEST_ASSERT_DOUBLE_WITHIN(1e-12, 3.0, vals[0] / scales[k]);
        TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1.0, vals[1] / scales[k]);
        TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1.0 / sqrt(2.0), fabs(vecs[0])); /* (1, 1)/sqrt 2, not the axes */
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_cholesky_known_factor);
    RUN_TEST(test_solve_and_mahalanobis);
    RUN_TEST(test_spd_inverse_times_a_is_identity);
    RUN_TEST(test_non_pd_is_reported);
    RUN_TEST(test_mahalanobis_reports_bad_arguments);
    RUN_TEST(test_mahalanobis_nonfinite_and_overflow);
    RUN_TEST(test_solve_reports_failures);
    RUN_TEST(test_logdet_reports_bad_arguments);
    RUN_TEST(test_jacobi_recovers_constructed_eigenpairs);
    RUN_TEST(test_jacobi_larger_matrix_is_orthonormal_decomposition);
    RUN_TEST(test_jacobi_reports_noconverge_and_bad_input);
    RUN_TEST(test_matmul_and_all_finite);
    RUN_TEST(test_jacobi_extreme_scales);
    return UNITY_END();
}
