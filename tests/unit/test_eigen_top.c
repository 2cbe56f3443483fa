/* Unit: eigen_top — the k leading eigenpairs against known spectra and against
 * the cyclic Jacobi solver, on the cases PCA meets: well separated, clustered
 * and repeated eigenvalues, an already tridiagonal or diagonal matrix, zero. */
#include <math.h>
#include <string.h>

#include "numeric/eigen_top.h"
#include "numeric/linalg.h"
#include "unity.h"

#define NMAX 48

static eigen_top_work_t g_ws;
static double g_a[NMAX * NMAX];
static double g_copy[NMAX * NMAX];
static double g_q[NMAX * NMAX];
static double g_jvals[NMAX];
static double g_jvecs[NMAX * NMAX];

void setUp(void) {}
void tearDown(void) {}

static unsigned g_seed = 12345u;
static double uniform(void)
{
    g_seed = g_seed * 1103515245u + 12345u;
    return (double)((g_seed >> 8) & 0xFFFFu) / 65536.0 - 0.5;
}

/* Random orthogonal Q (Gram-Schmidt of random columns), A = Q diag(lam) Qᵀ. */
static void make_matrix(size_t n, const double *lam)
{
    for (size_t k = 0; k < n * n; ++k) {
        g_q[k] = uniform();
    }
    for (size_t c = 0; c < n; ++c) {
        for (size_t p = 0; p < c; ++p) {
            double dot = 0.0;
            for (size_t r = 0; r < n; ++r) {
                dot += g_q[r * n + c] * g_q[r * n + p];
            }
            for (size_t r = 0; r < n; ++r) {
                g_q[r * n + c] -= dot * g_q[r * n + p];
            }
        }
        double ss = 0.0;
        for (size_t r = 0; r < n; ++r) {
            ss += g_q[r * n + c] * g_q[r * n + c];
        }
        for (size_t r = 0; r < n; ++r) {
            g_q[r * n + c] /= sqrt(ss);
        }
    }
    for (size_t i = 0; i < n; ++i) {
        for (size_t j = 0; j < n; ++j) {
            double s = 0.0;
            for (size_t k = 0; k < n; ++k) {
                s += g_q[i * n + k] * lam[k] * g_q[j * n + k];
            }
            g_a[i * n + j] = s;
        }
    }
    memcpy(g_copy, g_a, n * n * sizeof g_a[0]);
}

/* ‖A v - λ v‖ for row i of vecs, on the kept copy of A. */
static double residual(size_t n, const double *v, double lambda)
{
    double ss = 0.0;
    for (size_t r = 0; r < n; ++r) {
        double s = -lambda * v[r];
        for (size_t c = 0; c < n; ++c) {
            s += g_copy[r * n + c] * v[c];
        }
        ss += s * s;
    }
    return sqrt(ss);
}

static void check_pairs(size_t n, size_t k, const double *vals, const double *vecs, double norm)
{
    for (size_t i = 0; i < k; ++i) {
        TEST_ASSERT_TRUE(residual(n, &vecs[i * n], vals[i]) <= 1e-12 * norm);
        for (size_t j = 0; j <= i; ++j) {
            double dot = 0.0;
            for (size_t r = 0; r < n; ++r) {
                dot += vecs[i * n + r] * vecs[j * n + r];
            }
            TEST_ASSERT_DOUBLE_WITHIN(1e-12, (i == j) ? 1.0 : 0.0, dot);
        }
        if (i > 0) {
            TEST_ASSERT_TRUE(vals[i] <= vals[i - 1]);
        }
    }
}

static void test_known_spectrum_separated(void)
{
    const size_t n = 35;
    double lam[NMAX];
    for (size_t i = 0; i < n; ++i) {
        lam[i] = 1.0 / (1.0 + (double)i * (double)i); /* 1, 0.5, 0.2, 0.1, ... */
    }
    make_matrix(n, lam);
    double vals[4];
    double vecs[4 * NMAX];
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen_top(g_a, n, 4, vals, vecs, &g_ws));
    for (size_t i = 0; i < 4; ++i) {
        TEST_ASSERT_DOUBLE_WITHIN(1e-14, lam[i], vals[i]);
        double dot = 0.0; /* the known eigenvector, up to sign */
        for (size_t r = 0; r < n; ++r) {
            dot += vecs[i * n + r] * g_q[r * n + i];
        }
        TEST_ASSERT_DOUBLE_WITHIN(1e-10, 1.0, fabs(dot));
    }
    check_pairs(n, 4, vals, vecs, 1.0);
}

/* The PCA case: a signal direction over a flat noise floor, so λ2 ≈ λ3 ≈ ... */
static void test_noise_floor_cluster_matches_jacobi(void)
{
    const size_t n = 35;
    double lam[NMAX];
    for (size_t i = 0; i < n; ++i) {
        lam[i] = (i == 0) ? 40.0 : 1.0 + 1e-9 * (double)(n - i);
    }
    make_matrix(n, lam);
    double vals[3];
    double vecs[3 * NMAX];
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen_top(g_a, n, 3, vals, vecs, &g_ws));
    memcpy(g_a, g_copy, n * n * sizeof g_a[0]);
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen(g_a, n, g_jvals, g_jvecs, 60u));
    for (size_t i = 0; i < 3; ++i) {
        TEST_ASSERT_DOUBLE_WITHIN(1e-12 * 40.0, g_jvals[i], vals[i]);
    }
    check_pairs(n, 3, vals, vecs, 40.0);
}

static void test_repeated_eigenvalue_gets_orthogonal_vectors(void)
{
    const size_t n = 12;
    const double lam[12] = {3.0, 3.0, 3.0, 1.0, 0.5, 0.5, 0.2, 0.1, 0.0, 0.0, -0.3, -1.0};
    make_matrix(n, lam);
    double vals[4];
    double vecs[4 * NMAX];
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen_top(g_a, n, 4, vals, vecs, &g_ws));
    TEST_ASSERT_DOUBLE_WITHIN(1e-14 * 3.0, 3.0, vals[0]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-14 * 3.0, 3.0, vals[1]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-14 * 3.0, 3.0, vals[2]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-14 * 3.0, 1.0, vals[3]);
    check_pairs(n, 4, vals, vecs, 3.0);
}

/* Diagonal input: no reflector does anything, T splits into 1 x 1 blocks. */
static void test_diagonal_and_zero_matrix(void)
{
    const size_t n = 6;
    const double diag[6] = {0.5, -2.0, 4.0, 4.0, 1.0, 0.0};
    memset(g_a, 0, sizeof g_a);
    for (size_t i = 0; i < n; ++i) {
        g_a[i * n + i] = diag[i];
    }
    memcpy(g_copy, g_a, n * n * sizeof g_a[0]);
    double vals[3];
    double vecs[3 * NMAX];
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen_top(g_a, n, 3, vals, vecs, &g_ws));
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 4.0, vals[0]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 4.0, vals[1]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 1.0, vals[2]);
    check_pairs(n, 3, vals, vecs, 4.0);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1.0, fabs(vecs[2 * n + 4]));

    memset(g_a, 0, sizeof g_a);
    memset(g_copy, 0, sizeof g_copy);
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen_top(g_a, n, 2, vals, vecs, &g_ws));
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 0.0, vals[0]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 0.0, vals[1]);
    check_pairs(n, 2, vals, vecs, 1.0);
}

static void test_small_orders(void)
{
    double one = -7.5;
    double v1 = 0.0;
    double e1 = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen_top(&one, 1, 1, &v1, &e1, &g_ws));
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, -7.5, v1);
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 1.0, fabs(e1));

    double a2[4] = {2.0, 1.0, 1.0, 2.0}; /* eigenvalues 3 (1,1)/√2 and 1 */
    memcpy(g_copy, a2, sizeof a2);
    double vals[2];
    double vecs[4];
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen_top(a2, 2, 2, vals, vecs, &g_ws));
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 3.0, vals[0]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 1.0, vals[1]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, fabs(vecs[0]), fabs(vecs[1]));
    check_pairs(2, 2, vals, vecs, 3.0);
}

/* Only the lower triangle is input: garbage above the diagonal changes nothing. */
static void test_reads_lower_triangle_only(void)
{
    const size_t n = 20;
    double lam[NMAX];
    for (size_t i = 0; i < n; ++i) {
        lam[i] = (double)(n - i);
    }
    make_matrix(n, lam);
    for (size_t r = 0; r < n; ++r) {
        for (size_t c = r + 1; c < n; ++c) {
            g_a[r * n + c] = 1e6 * uniform();
        }
    }
    double vals[2];
    double vecs[2 * NMAX];
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen_top(g_a, n, 2, vals, vecs, &g_ws));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12 * 20.0, 20.0, vals[0]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12 * 20.0, 19.0, vals[1]);
    check_pairs(n, 2, vals, vecs, 20.0);
}

/* Columns whose entries below the diagonal are ~1e-158: their squares fall into
 * the subnormal range. A rank-1 matrix plus rounding-level noise, as PCA gets
 * from identical-but-one windows (fuzz_pca): the zero cluster's vectors must
 * still be orthonormal. */
static void test_tiny_columns_keep_reflectors_orthogonal(void)
{
    const size_t n = 16;
    double v[NMAX];
    for (size_t i = 0; i < n; ++i) {
        v[i] = (i % 3u == 0u) ? 1.0 : 1e-158 * (double)(i + 1u);
    }
    for (size_t r = 0; r < n; ++r) {
        for (size_t c = 0; c < n; ++c) {
            g_a[r * n + c] = v[r] * v[c] + ((r == c) ? 1e-300 * (double)(r + 1u) : 0.0);
        }
    }
    memcpy(g_copy, g_a, n * n * sizeof g_a[0]);
    double vals[3];
    double vecs[3 * NMAX];
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen_top(g_a, n, 3, vals, vecs, &g_ws));
    TEST_ASSERT_DOUBLE_WITHIN(1e-14 * 6.0, 6.0, vals[0]);
    check_pairs(n, 3, vals, vecs, 6.0);
}

/* A column that is e1 but for entries near 1e-80 (fuzz_pca finding 7): with
 * the reflector of Golub & Van Loan, v_0 = -σ/(x_0 + ‖x‖) ≈ 1e-160 and v_0²
 * is subnormal; the sign convention of dlarfg avoids the cancellation. */
static void test_nearly_reduced_column_keeps_reflectors_orthogonal(void)
{
    const size_t n = 14;
    memset(g_a, 0, sizeof g_a);
    for (size_t r = 0; r < n; ++r) {
        g_a[r * n + r] = 1.0 + 0.37 * (double)((r * 5u) % n);
        if (r + 1u < n) {
            g_a[r * n + r + 1u] = g_a[(r + 1u) * n + r] = 0.6;
        }
        for (size_t c = r + 2u; c < n; ++c) {
            g_a[r * n + c] = g_a[c * n + r] = 1e-80 * (double)(r + c);
        }
    }
    memcpy(g_copy, g_a, n * n * sizeof g_a[0]);
    double vals[3];
    double vecs[3 * NMAX];
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen_top(g_a, n, 3, vals, vecs, &g_ws));
    memcpy(g_a, g_copy, n * n * sizeof g_a[0]);
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen(g_a, n, g_jvals, g_jvecs, 80u));
    for (size_t i = 0; i < 3; ++i) {
        TEST_ASSERT_DOUBLE_WITHIN(1e-13 * g_jvals[0], g_jvals[i], vals[i]);
    }
    check_pairs(n, 3, vals, vecs, g_jvals[0]);
}

static void test_bad_arguments_and_non_finite_input(void)
{
    double a[4] = {1.0, 0.0, 0.0, 1.0};
    double vals[4];
    double vecs[8];
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_sym_eigen_top(NULL, 2, 1, vals, vecs, &g_ws));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_sym_eigen_top(a, 2, 0, vals, vecs, &g_ws));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_sym_eigen_top(a, 2, 3, vals, vecs, &g_ws));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_sym_eigen_top(a, 0, 1, vals, vecs, &g_ws));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_sym_eigen_top(a, LINALG_MAX_N + 1u, 1, vals, vecs, &g_ws));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, linalg_sym_eigen_top(a, 2, 1, vals, vecs, NULL));
    a[2] = NAN;
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, linalg_sym_eigen_top(a, 2, 1, vals, vecs, &g_ws));
    a[2] = 0.0;
    a[1] = NAN; /* above the diagonal: not input */
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen_top(a, 2, 1, vals, vecs, &g_ws));
}

/* Many random spectra against Jacobi: eigenvalues and residuals. */
static void test_random_matrices_match_jacobi(void)
{
    for (unsigned trial = 0; trial < 40; ++trial) {
        const size_t n = 2u + (size_t)(trial % 47u);
        double lam[NMAX];
        for (size_t i = 0; i < n; ++i) {
            lam[i] = (trial % 3u == 0u) ? uniform() : exp(8.0 * uniform());
        }
        make_matrix(n, lam);
        double vals[3];
        double vecs[3 * NMAX];
        const size_t k = (n < 3u) ? n : 3u;
        TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen_top(g_a, n, k, vals, vecs, &g_ws));
        memcpy(g_a, g_copy, n * n * sizeof g_a[0]);
        TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen(g_a, n, g_jvals, g_jvecs, 80u));
        double norm = 0.0;
        for (size_t i = 0; i < n; ++i) {
            norm = fmax(norm, fabs(g_jvals[i]));
        }
        for (size_t i = 0; i < k; ++i) {
            TEST_ASSERT_DOUBLE_WITHIN(1e-12 * norm, g_jvals[i], vals[i]);
        }
        check_pairs(n, k, vals, vecs, norm);
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_known_spectrum_separated);
    RUN_TEST(test_noise_floor_cluster_matches_jacobi);
    RUN_TEST(test_repeated_eigenvalue_gets_orthogonal_vectors);
    RUN_TEST(test_diagonal_and_zero_matrix);
    RUN_TEST(test_small_orders);
    RUN_TEST(test_reads_lower_triangle_only);
    RUN_TEST(test_tiny_columns_keep_reflectors_orthogonal);
    RUN_TEST(test_nearly_reduced_column_keeps_reflectors_orthogonal);
    RUN_TEST(test_bad_arguments_and_non_finite_input);
    RUN_TEST(test_random_matrices_match_jacobi);
    return UNITY_END();
}
