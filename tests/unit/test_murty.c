/* Unit: lap + murty — the L best assignments equal brute-force enumeration,
 * in order, on random rectangular matrices with forbidden entries and ties,
 * at every size the tracker uses (up to LAP_MAX_ROWS × LAP_MAX_COLS). */
#include <math.h>

#include "numeric/md_rng.h"
#include "tracking/murty.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static double cost_matrix[LAP_MAX_ROWS * LAP_MAX_COLS];
static murty_workspace_t workspace;

typedef struct {
    double cost[MURTY_MAX_L];
    size_t count;
    size_t feasible;
} brute_t;

/* Keeps the L smallest costs seen, sorted ascending. */
static void brute_offer(brute_t *b, double c, size_t L)
{
    b->feasible++;
    size_t pos = b->count;
    while (pos > 0u && b->cost[pos - 1u] > c) {
        if (pos < L) {
            b->cost[pos] = b->cost[pos - 1u];
        }
        pos--;
    }
    if (pos < L) {
        b->cost[pos] = c;
        if (b->count < L) {
            b->count++;
        }
    }
}

/* Odometer over every column tuple (no recursion). */
static void brute_force(size_t rows, size_t cols, size_t L, brute_t *b)
{
    size_t col[LAP_MAX_ROWS] = {0};
    b->count = 0u;
    b->feasible = 0u;
    for (;;) {
        uint32_t used = 0u;
        int ok = 1;
        double c = 0.0;
        for (size_t r = 0u; r < rows && ok; ++r) {
            const double v = cost_matrix[r * cols + col[r]];
            ok = (used & (1u << col[r])) == 0u && v < LAP_FORBIDDEN;
            used |= 1u << col[r];
            c += v;
        }
        if (ok) {
            brute_offer(b, c, L);
        }
        size_t r = 0u;
        while (r < rows && ++col[r] == cols) {
            col[r++] = 0u;
        }
        if (r == rows) {
            return;
        }
    }
}

static void fill_random(md_rng_t *rng, size_t rows, size_t cols, int integer_costs, double p_forbidden)
{
    for (size_t k = 0u; k < rows * cols; ++k) {
        if (md_rng_uniform(rng) < p_forbidden) {
            cost_matrix[k] = LAP_FORBIDDEN;
        } else if (integer_costs) {
            cost_matrix[k] = (double)md_rng_below(rng, 4u) - 1.0; /* many ties, some negative */
        } else {
            cost_matrix[k] = 10.0 * md_rng_gauss(rng);
        }
    }
}

static void check_solution(const lap_solution_t *s, size_t rows, size_t cols)
{
    uint32_t used = 0u;
    double c = 0.0;
    for (size_t r = 0u; r < rows; ++r) {
        const int col = s->col_of_row[r];
        TEST_ASSERT_TRUE(col >= 0 && (size_t)col < cols);
        TEST_ASSERT_TRUE((used & (1u << col)) == 0u);
        used |= 1u << col;
        TEST_ASSERT_TRUE(cost_matrix[r * cols + (size_t)col] < LAP_FORBIDDEN);
        c += cost_matrix[r * cols + (size_t)col];
    }
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, c, s->cost);
}

static void check_distinct(const lap_solution_t *s, size_t n, size_t rows)
{
    for (size_t a = 0u; a < n; ++a) {
        for (size_t b = a + 1u; b < n; ++b) {
            int same = 1;
            for (size_t r = 0u; r < rows; ++r) {
                same = same && s[a].col_of_row[r] == s[b].col_of_row[r];
            }
            TEST_ASSERT_FALSE(same);
        }
    }
}

static void compare_with_brute_force(size_t rows, size_t cols, size_t L)
{
    lap_solution_t got[MURTY_MAX_L];
    size_t n = 99u;
    brute_t want;
    TEST_ASSERT_EQUAL_INT(MD_OK, murty_best(cost_matrix, rows, cols, L, &workspace, got, &n));
    brute_force(rows, cols, L, &want);
    TEST_ASSERT_EQUAL_UINT(want.count, n);
    for (size_t i = 0u; i < n; ++i) {
        check_solution(&got[i], rows, cols);
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, want.cost[i], got[i].cost);
    }
    check_distinct(got, n, rows);
}

static void test_random_real_costs_match_brute_force(void)
{
    md_rng_t rng;
    md_rng_seed(&rng, 11u);
    for (unsigned trial = 0u; trial < 60u; ++trial) {
        const size_t rows = 1u + md_rng_below(&rng, LAP_MAX_ROWS);
        const size_t cols = rows + md_rng_below(&rng, (uint32_t)(LAP_MAX_COLS - rows + 1u));
        fill_random(&rng, rows, cols, 0, 0.15);
        compare_with_brute_force(rows, cols, MURTY_MAX_L);
    }
}

static void test_ties_and_forbidden_entries_match_brute_force(void)
{
    md_rng_t rng;
    md_rng_seed(&rng, 12u);
    for (unsigned trial = 0u; trial < 60u; ++trial) {
        const size_t rows = 1u + md_rng_below(&rng, LAP_MAX_ROWS);
        const size_t cols = rows + md_rng_below(&rng, (uint32_t)(LAP_MAX_COLS - rows + 1u));
        fill_random(&rng, rows, cols, 1, 0.4);
        compare_with_brute_force(rows, cols, 1u + md_rng_below(&rng, MURTY_MAX_L));
    }
}

static void test_largest_size_used_by_the_tracker(void)
{
    md_rng_t rng;
    md_rng_seed(&rng, 13u);
    for (unsigned trial = 0u; trial < 5u; ++trial) {
        fill_random(&rng, LAP_MAX_ROWS, LAP_MAX_COLS, (int)(trial & 1u), 0.2);
        compare_with_brute_force(LAP_MAX_ROWS, LAP_MAX_COLS, MURTY_MAX_L);
    }
}

static void test_fewer_feasible_than_L_returns_all_of_them(void)
{
    /* 2×2 with one forbidden pair: exactly one feasible assignment. */
    const double c[4] = {1.0, LAP_FORBIDDEN, 2.0, 3.0};
    lap_solution_t got[MURTY_MAX_L];
    size_t n = 0u;
    TEST_ASSERT_EQUAL_INT(MD_OK, murty_best(c, 2u, 2u, MURTY_MAX_L, &workspace, got, &n));
    TEST_ASSERT_EQUAL_UINT(1u, n);
    TEST_ASSERT_EQUAL_INT(0, got[0].col_of_row[0]);
    TEST_ASSERT_EQUAL_INT(1, got[0].col_of_row[1]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 4.0, got[0].cost);
}

static void test_infeasible_problem_gives_no_solution(void)
{
    const double c[4] = {1.0, LAP_FORBIDDEN, 2.0, LAP_FORBIDDEN};
    lap_solution_t got[MURTY_MAX_L];
    size_t n = 7u;
    TEST_ASSERT_EQUAL_INT(MD_OK, murty_best(c, 2u, 2u, 3u, &workspace, got, &n));
    TEST_ASSERT_EQUAL_UINT(0u, n);
}

static void test_bad_input_is_rejected(void)
{
    double c[4] = {1.0, 2.0, 3.0, 4.0};
    lap_solution_t got[MURTY_MAX_L];
    size_t n = 0u;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, murty_best(c, 3u, 2u, 1u, &workspace, got, &n));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, murty_best(c, 2u, 2u, 0u, &workspace, got, &n));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, murty_best(c, 2u, 2u, MURTY_MAX_L + 1u, &workspace, got, &n));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, murty_best(c, 0u, 2u, 1u, &workspace, got, &n));
    c[1] = NAN;
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, murty_best(c, 2u, 2u, 1u, &workspace, got, &n));
}

static void test_pinned_rows_are_respected_by_lap(void)
{
    const double c[6] = {0.0, 5.0, 9.0, 0.0, 1.0, 9.0};
    lap_problem_t p;
    lap_solution_t s;
    TEST_ASSERT_EQUAL_INT(MD_OK, lap_problem_init(&p, c, 2u, 3u));
    p.fixed_col[1] = 0; /* row 1 pinned to column 0, which row 0 would prefer */
    TEST_ASSERT_EQUAL_INT(MD_OK, lap_solve(&p, &s));
    TEST_ASSERT_EQUAL_INT(1, s.col_of_row[0]);
    TEST_ASSERT_EQUAL_INT(0, s.col_of_row[1]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 5.0, s.cost);
    p.fixed_col[0] = 0; /* two rows pinned to one column */
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, lap_solve(&p, &s));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_random_real_costs_match_brute_force);
    RUN_TEST(test_ties_and_forbidden_entries_match_brute_force);
    RUN_TEST(test_largest_size_used_by_the_tracker);
    RUN_TEST(test_fewer_feasible_than_L_returns_all_of_them);
    RUN_TEST(test_infeasible_problem_gives_no_solution);
    RUN_TEST(test_bad_input_is_rejected);
    RUN_TEST(test_pinned_rows_are_respected_by_lap);
    return UNITY_END();
}
