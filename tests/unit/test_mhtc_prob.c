/// @file test_mhtc_prob.c
/// P3 (eq. 4.32) against brute-force enumeration of detection patterns, and
/// Prop. 4.2: the product of A's entries over any legal hypothesis is eq. 4.24
/// up to one constant per model; Murty's best equals the brute-force best.
#include <math.h>
#include <string.h>

#include "numeric/md_rng.h"
#include "tracking/mhtc_prob.h"
#include "tracking/murty.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static double poisson(double lam, size_t n)
{
    double f = 1.0;
    for (size_t i = 2u; i <= n; ++i) {
        f *= (double)i;
    }
    return pow(lam, (double)n) * exp(-lam) / f;
}

/* eq. 4.31-4.32 written as a sum over every δ ∈ {0,1}^{N_t}. */
static double p3_brute(const double *pd, size_t nt, size_t g, double l0)
{
    double s = 0.0;
    for (uint32_t mask = 0u; mask < (1u << nt); ++mask) {
        double p = 1.0;
        size_t tau = 0u;
        for (size_t j = 0u; j < nt; ++j) {
            const int det = (int)((mask >> j) & 1u);
            p *= det ? pd[j] : 1.0 - pd[j];
            tau += (size_t)det;
        }
        if (tau <= g) {
            s += p * poisson(l0, g - tau);
        }
    }
    return s;
}

static void test_p3_matches_brute_force(void)
{
    md_rng_t rng;
    md_rng_seed(&rng, 3u);
    for (size_t trial = 0u; trial < 200u; ++trial) {
        const size_t nt = (size_t)md_rng_below(&rng, MHTC_PROB_NT_MAX + 1u);
        const size_t g = 1u + (size_t)md_rng_below(&rng, MD_G_MAX);
        double pd[MHTC_PROB_NT_MAX];
        for (size_t j = 0u; j < nt; ++j) {
            pd[j] = 0.05 + 0.9 * md_rng_uniform(&rng);
        }
        const double l0 = 0.001 + 2.0 * md_rng_uniform(&rng);
        double lp = 0.0;
        TEST_ASSERT_EQUAL_INT(MD_OK, mhtc_log_p3(pd, nt, g, l0, &lp));
        const double ref = p3_brute(pd, nt, g, l0);
        TEST_ASSERT_DOUBLE_WITHIN(1e-12 * fabs(log(ref)) + 1e-12, log(ref), lp);
    }
    double lp = 0.0;
    const double pd_bad[1] = {1.0};
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, mhtc_log_p3(pd_bad, 1u, 1u, 0.025, &lp));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, mhtc_log_p3(NULL, 0u, 1u, 0.0, &lp));
}

static void test_p3_table_values(void)
{
    /* no targets, Table 4.1 λ0 = 0.025: P3(G) = Poisson(G; λ0) */
    double lp = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, mhtc_log_p3(NULL, 0u, 2u, 0.025, &lp));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, log(0.025 * 0.025 * exp(-0.025) / 2.0), lp);
    /* one target at P_d = 0.9, G = 1: P_d·e^{-λ0} + (1 - P_d)·λ0·e^{-λ0} */
    const double pd[1] = {0.9};
    TEST_ASSERT_EQUAL_INT(MD_OK, mhtc_log_p3(pd, 1u, 1u, 0.025, &lp));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, log((0.9 + 0.1 * 0.025) * exp(-0.025)), lp);
}

/* A random instance in the form of eq. 4.26: targets with P_d, f_N values of each measurement. */
typedef struct {
    size_t g, nt;
    double pd[4];
    double fn[MD_G_MAX][4]; /* f_N(μ_g | μ̂_j, S_j) */
    double volume, ln, lf;
    double zeta[MD_G_MAX][5];
} inst_t;

static void make_instance(md_rng_t *rng, inst_t *in)
{
    in->g = 1u + (size_t)md_rng_below(rng, 3u);
    in->nt = (size_t)md_rng_below(rng, 4u);
    in->volume = 50.0 + 100.0 * md_rng_uniform(rng);
    in->ln = 0.01;
    in->lf = 0.015;
    for (size_t j = 0u; j < in->nt; ++j) {
        in->pd[j] = 0.75 + 0.23 * md_rng_uniform(rng);
    }
    for (size_t r = 0u; r < in->g; ++r) {
        /* densities spanning many orders of magnitude; some exactly zero (far away) */
        for (size_t j = 0u; j < in->nt; ++j) {
            in->fn[r][j] = (md_rng_uniform(rng) < 0.15) ? 0.0 : exp(-12.0 * md_rng_uniform(rng));
        }
        double b = (in->ln + in->lf) / in->volume; /* eq. 4.28 (ω up to the common 1/c) */
        for (size_t j = 0u; j < in->nt; ++j) {
            b += in->pd[j] * in->fn[r][j];
        }
        in->zeta[r][0] = (in->ln + in->lf) / in->volume / b;
        for (size_t j = 0u; j < in->nt; ++j) {
            in->zeta[r][j + 1u] = in->pd[j] * in->fn[r][j] / b; /* eq. 4.26 */
        }
    }
}

/* eq. 4.24 (without A_m) of the assignment col_of_row; 0 if illegal. */
static double eq_4_24(const inst_t *in, const int *col)
{
    double p = 1.0;
    for (size_t j = 0u; j < in->nt; ++j) {
        bool det = false;
        for (size_t r = 0u; r < in->g; ++r) {
            det = det || (col[r] == (int)j);
        }
        p *= det ? in->pd[j] : 1.0 - in->pd[j];
    }
    for (size_t r = 0u; r < in->g; ++r) {
        if (col[r] < (int)in->nt) {
            p *= in->fn[r][col[r]];
        } else {
            p *= ((col[r] == (int)in->nt) ? in->ln : in->lf) / in->volume;
        }
    }
    return p;
}

/* Columns of the hypothesis in A's layout (eq. 4.29: h̃). */
static double a_product(const inst_t *in, const double *cost, const int *col)
{
    const size_t cols = in->nt + 2u * in->g;
    double s = 0.0;
    for (size_t r = 0u; r < in->g; ++r) {
        size_t c = (size_t)col[r];
        if (col[r] == (int)in->nt) {
            c = in->nt + r;
        } else if (col[r] == (int)in->nt + 1) {
            c = in->nt + in->g + r;
        }
        if (cost[r * cols + c] >= LAP_FORBIDDEN) {
            return 0.0;
        }
        s += cost[r * cols + c];
    }
    return exp(-s);
}

static void test_prop_4_2_product_of_a(void)
{
    md_rng_t rng;
    md_rng_seed(&rng, 42u);
    static murty_workspace_t mws;
    for (size_t trial = 0u; trial < 300u; ++trial) {
        inst_t in;
        make_instance(&rng, &in);
        double cost[LAP_MAX_ROWS * LAP_MAX_COLS];
        TEST_ASSERT_EQUAL_INT(MD_OK,
                              mhtc_assoc_costs(&in.zeta[0][0], 5u, in.g, in.pd, in.nt, in.ln, in.lf, NULL, cost));
        /* odometer over (nt + 2)^g labels: j < nt target, nt new, nt+1 false */
        const size_t base = in.nt + 2u;
        size_t combos = 1u;
        for (size_t r = 0u; r < in.g; ++r) {
            combos *= base;
        }
        double ratio = -1.0, best = 0.0;
        for (size_t code = 0u; code < combos; ++code) {
            int col[MD_G_MAX];
            size_t c = code;
            bool legal = true;
            for (size_t r = 0u; r < in.g; ++r) {
                col[r] = (int)(c % base);
                c /= base;
                for (size_t r2 = 0u; r2 < r; ++r2) {
                    legal = legal && !((col[r] < (int)in.nt) && (col[r2] == col[r]));
                }
            }
            if (!legal) {
                continue;
            }
            const double p = eq_4_24(&in, col);
            const double a = a_product(&in, cost, col);
            TEST_ASSERT_EQUAL(p > 0.0, a > 0.0); /* zeros of A are exactly the impossible hypotheses */
            best = fmax(best, p);
            if (p > 0.0) {
                const double ra = p / a; /* the constant D of eq. 4.27 */
                if (ratio < 0.0) {
                    ratio = ra;
                }
                TEST_ASSERT_DOUBLE_WITHIN(1e-9 * ratio, ratio, ra);
            }
        }
        /* Murty's cheapest assignment is the most plausible hypothesis */
        lap_solution_t sol[1];
        size_t n = 0u;
        TEST_ASSERT_EQUAL_INT(MD_OK, murty_best(cost, in.g, in.nt + 2u * in.g, 1u, &mws, sol, &n));
        TEST_ASSERT_EQUAL_size_t(1u, n);
        TEST_ASSERT_DOUBLE_WITHIN(1e-9 * best, best, ratio * exp(-sol[0].cost));
    }
}

static void test_costs_forbid_off_diagonal_and_bad_input(void)
{
    const double zeta[2][3] = {{0.5, 0.5, 0.0}, {0.2, 0.3, 0.5}};
    const double pd[2] = {0.9, 0.8};
    double cost[2 * 6];
    TEST_ASSERT_EQUAL_INT(MD_OK, mhtc_assoc_costs(&zeta[0][0], 3u, 2u, pd, 2u, 0.01, 0.015, NULL, cost));
    TEST_ASSERT_TRUE(cost[0 * 6 + 1] >= LAP_FORBIDDEN); /* ζ = 0 */
    TEST_ASSERT_TRUE(cost[0 * 6 + 3] >= LAP_FORBIDDEN); /* row 0, new column of row 1 */
    TEST_ASSERT_TRUE(cost[1 * 6 + 4] >= LAP_FORBIDDEN); /* row 1, false column of row 0 */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, -log(0.5 / 0.1), cost[0]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, -log(0.4 * 0.2), cost[1 * 6 + 3]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, -log(0.6 * 0.2), cost[1 * 6 + 5]);
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, mhtc_assoc_costs(&zeta[0][0], 2u, 2u, pd, 2u, 0.01, 0.015, NULL, cost));
    const double pd1[2] = {1.0, 0.8};
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, mhtc_assoc_costs(&zeta[0][0], 3u, 2u, pd1, 2u, 0.01, 0.015, NULL, cost));
    const double zn[1][1] = {{NAN}};
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, mhtc_assoc_costs(&zn[0][0], 1u, 1u, NULL, 0u, 0.01, 0.015, NULL, cost));
}

/* A neuron's main cluster (90 spikes) and its burst spikes (10) against a track that had 88: the
 * count term makes the swap (burst cluster continues the track) cost ln²(11/89)/(2σ²) more, and
 * leaves births, false alarms and unknown counts alone. */
static void test_count_term(void)
{
    const double zeta[2][2] = {{0.1, 0.9}, {0.1, 0.9}}; /* both clusters fit the track equally */
    const double pd[1] = {0.9};
    const double n_cluster[2] = {90.0, 10.0};
    const double n_expect[1] = {88.0};
    const double sigma = 0.5;
    double off[2 * 5];
    double on[2 * 5];
    const mhtc_count_term_t count = {n_cluster, n_expect, NULL, sigma};
    TEST_ASSERT_EQUAL_INT(MD_OK, mhtc_assoc_costs(&zeta[0][0], 2u, 2u, pd, 1u, 0.01, 0.015, NULL, off));
    TEST_ASSERT_EQUAL_INT(MD_OK, mhtc_assoc_costs(&zeta[0][0], 2u, 2u, pd, 1u, 0.01, 0.015, &count, on));
    const double l_main = log(91.0 / 89.0);
    const double l_burst = log(11.0 / 89.0);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, off[0] + l_main * l_main / (2.0 * sigma * sigma), on[0]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, off[5] + l_burst * l_burst / (2.0 * sigma * sigma), on[5]);
    TEST_ASSERT_TRUE(on[5] - on[0] > 8.0); /* the swap is no longer a coin toss */
    for (size_t c = 1u; c < 5u; ++c) {     /* births and false alarms unchanged */
        TEST_ASSERT_EQUAL_DOUBLE(off[c], on[c]);
        TEST_ASSERT_EQUAL_DOUBLE(off[5u + c], on[5u + c]);
    }
    const double unknown[1] = {0.0}; /* no detection yet: no term */
    const mhtc_count_term_t none = {n_cluster, unknown, NULL, sigma};
    TEST_ASSERT_EQUAL_INT(MD_OK, mhtc_assoc_costs(&zeta[0][0], 2u, 2u, pd, 1u, 0.01, 0.015, &none, on));
    TEST_ASSERT_EQUAL_DOUBLE(off[5], on[5]);
    const mhtc_count_term_t zero = {NULL, NULL, NULL, 0.0}; /* σ = 0: off, arrays not read */
    TEST_ASSERT_EQUAL_INT(MD_OK, mhtc_assoc_costs(&zeta[0][0], 2u, 2u, pd, 1u, 0.01, 0.015, &zero, on));
    TEST_ASSERT_EQUAL_DOUBLE(off[5], on[5]);
    const mhtc_count_term_t negative = {n_cluster, n_expect, NULL, -0.5};
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, mhtc_assoc_costs(&zeta[0][0], 2u, 2u, pd, 1u, 0.01, 0.015, &negative, on));
    const mhtc_count_term_t nan_sigma = {n_cluster, n_expect, NULL, NAN};
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, mhtc_assoc_costs(&zeta[0][0], 2u, 2u, pd, 1u, 0.01, 0.015, &nan_sigma, on));
    const double bad_count[2] = {90.0, INFINITY};
    const mhtc_count_term_t inf_count = {bad_count, n_expect, NULL, sigma};
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, mhtc_assoc_costs(&zeta[0][0], 2u, 2u, pd, 1u, 0.01, 0.015, &inf_count, on));
    const mhtc_count_term_t no_counts = {NULL, n_expect, NULL, sigma};
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, mhtc_assoc_costs(&zeta[0][0], 2u, 2u, pd, 1u, 0.01, 0.015, &no_counts, on));
    const double two[1] = {2.0}; /* a track that missed once: σ doubled, a quarter of the cost */
    const mhtc_count_term_t missed = {n_cluster, n_expect, two, sigma};
    TEST_ASSERT_EQUAL_INT(MD_OK, mhtc_assoc_costs(&zeta[0][0], 2u, 2u, pd, 1u, 0.01, 0.015, &missed, on));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, off[5] + l_burst * l_burst / (8.0 * sigma * sigma), on[5]);
    const double below_one[1] = {0.5};
    const mhtc_count_term_t narrow = {n_cluster, n_expect, below_one, sigma};
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, mhtc_assoc_costs(&zeta[0][0], 2u, 2u, pd, 1u, 0.01, 0.015, &narrow, on));
}

/* A track's count reference: the median of its last three detected counts, its last count while
 * it has fewer; one interval's dip (a split cluster, a neuron silent for part of it) is outvoted. */
static void test_count_reference_is_the_median_of_three_detections(void)
{
    const double full[2] = {100.0, 96.0};
    TEST_ASSERT_EQUAL_DOUBLE(96.0, mhtc_count_reference(40.0, full));
    const double dip[2] = {40.0, 100.0};
    TEST_ASSERT_EQUAL_DOUBLE(100.0, mhtc_count_reference(104.0, dip));
    const double rising[2] = {60.0, 20.0};
    TEST_ASSERT_EQUAL_DOUBLE(60.0, mhtc_count_reference(100.0, rising));
    const double one_before[2] = {100.0, -1.0};
    TEST_ASSERT_EQUAL_DOUBLE(40.0, mhtc_count_reference(40.0, one_before));
    const double none[2] = {-1.0, -1.0};
    TEST_ASSERT_EQUAL_DOUBLE(40.0, mhtc_count_reference(40.0, none));
}

static void test_pd_rule(void)
{
    const mhtc_pd_rule_t rule = {0.98, 0.75, 0.6, 4.0};
    /* q(10) = ½(P_max + P_min) by the choice of a and b (§4.4.2) */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.98 - 1.0 / 10.0, mhtc_pd_first(&rule, 10.0));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.75, mhtc_pd_first(&rule, 0.0)); /* clamped */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.5 * (0.88 + 0.9), mhtc_pd_next(&rule, 0.9, 10.0));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.75, mhtc_pd_next(&rule, 0.75, 0.0));
    TEST_ASSERT_TRUE(mhtc_pd_next(&rule, 0.98, 1e6) <= 0.98);
}

static void test_log_norm(void)
{
    const double c[3] = {1.0, 2.0, 1000.0};
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, log(exp(-1.0) + exp(-2.0) + exp(-1000.0)), mhtc_log_norm(c, 3u));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_p3_matches_brute_force);
    RUN_TEST(test_p3_table_values);
    RUN_TEST(test_prop_4_2_product_of_a);
    RUN_TEST(test_costs_forbid_off_diagonal_and_bad_input);
    RUN_TEST(test_count_term);
    RUN_TEST(test_count_reference_is_the_median_of_three_detections);
    RUN_TEST(test_pd_rule);
    RUN_TEST(test_log_norm);
    return UNITY_END();
}
