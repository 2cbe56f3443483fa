/* Unit: quality metrics — SNR, isolation distance and noise covariance on
 * constructed clusters with hand-computed answers. */
#include <math.h>
#include <string.h>

#include "metrics/quality.h"
#include "unity.h"

#define STRIDE 8u

void setUp(void) {}
void tearDown(void) {}

static void test_noise_rms_and_snr(void)
{
    double noise[3 * STRIDE];
    for (size_t i = 0u; i < 3u * STRIDE; ++i) {
        noise[i] = (i % 2u) ? 2.0 : -2.0;
    }
    double rms = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, qm_noise_rms(noise, 3u, STRIDE, 5u, &rms));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 2.0, rms);
    /* three waveforms of 5 samples; labels 1, 2, 1; ptp 10 and 14 for label 1 */
    double wave[3 * STRIDE];
    memset(wave, 0, sizeof wave);
    const double w0[5] = {0, -8, 2, 1, 0};
    const double w1[5] = {0, -3, 1, 0, 0};
    const double w2[5] = {1, -10, 4, 0, 0};
    memcpy(&wave[0], w0, sizeof w0);
    memcpy(&wave[STRIDE], w1, sizeof w1);
    memcpy(&wave[2u * STRIDE], w2, sizeof w2);
    wave[7] = 100.0; /* beyond d_w: must be ignored */
    const uint8_t labels[3] = {1, 2, 1};
    double snr = 0.0;
    size_t members = 0u;
    TEST_ASSERT_EQUAL_INT(MD_OK, qm_snr(wave, 3u, STRIDE, 5u, labels, 1u, rms, &snr, &members));
    TEST_ASSERT_EQUAL_size_t(2u, members);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, (10.0 + 14.0) / 2.0 / 2.0, snr);
    TEST_ASSERT_EQUAL_INT(MD_OK, qm_snr(wave, 3u, STRIDE, 5u, NULL, 0u, rms, &snr, &members));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, (10.0 + 4.0 + 14.0) / 3.0 / 2.0, snr);
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, qm_snr(wave, 3u, STRIDE, 5u, labels, 3u, rms, &snr, &members));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, qm_snr(wave, 3u, STRIDE, 5u, labels, 1u, 0.0, &snr, &members));
    double zero[STRIDE] = {0};
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, qm_noise_rms(zero, 1u, STRIDE, 5u, &rms));
}

static void test_isolation_distance_given_sigma(void)
{
    /* cluster 1: 3 members; Σ = diag(4, 1), μ = (1, 0). Non-members at
     * squared distances 1, 4, 9, 16 (spikes) and 2.25 (noise): the 3rd closest
     * is 4 -> ID^2 = 4, ID = 2. */
    const double y[7 * 2] = {1, 0.1, 1.2, 0, 0.9, -0.1, /* members */
                             3, 0,                      /* (2/2)^2 = 1 */
                             1, 2,                      /* 4 */
                             7, 0,                      /* 9 */
                             1, -4};                    /* 16 */
    const uint8_t labels[7] = {1, 1, 1, 0, 2, 2, 0};
    const double noise[2] = {1, 1.5}; /* 2.25 */
    const double mu[2] = {1, 0};
    const double cov[4] = {4, 0, 0, 1};
    double work[16];
    qm_isolation_t iso;
    TEST_ASSERT_EQUAL_INT(MD_OK, qm_isolation_distance(y, 7u, 2u, labels, 1u, noise, 1u, mu, cov, work, 16u, &iso));
    TEST_ASSERT_TRUE(iso.defined);
    TEST_ASSERT_EQUAL_size_t(3u, iso.n_members);
    TEST_ASSERT_EQUAL_size_t(5u, iso.n_nonmembers);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 4.0, iso.id2);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 2.0, iso.id);
    /* without the noise point the 3rd closest spike is at 9 */
    TEST_ASSERT_EQUAL_INT(MD_OK, qm_isolation_distance(y, 7u, 2u, labels, 1u, NULL, 0u, mu, cov, work, 16u, &iso));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 9.0, iso.id2);
    /* cluster 2 has 2 members; a singular Σ is reported */
    const double bad[4] = {1, 1, 1, 1};
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC,
                          qm_isolation_distance(y, 7u, 2u, labels, 2u, NULL, 0u, mu, bad, work, 16u, &iso));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, qm_isolation_distance(y, 7u, 2u, labels, 1u, noise, 1u, mu, cov, work, 7u, &iso));
    /* a non-finite point has no distance: reported, not ranked */
    const double nan_noise[2] = {NAN, 1.5};
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC,
                          qm_isolation_distance(y, 7u, 2u, labels, 1u, nan_noise, 1u, mu, cov, work, 16u, &iso));
    TEST_ASSERT_FALSE(iso.defined);
}

static void test_isolation_distance_estimated_and_undefined(void)
{
    /* members (+-1, 0), (0, +-1): mean 0, sample covariance (2/3) I.
     * Non-members (2,0) (0,3) (3,0) (0,4): D^2 = 6, 13.5, 13.5, 24; n_g = 4. */
    const double y[8 * 2] = {1, 0, -1, 0, 0, 1, 0, -1, 2, 0, 0, 3, 3, 0, 0, 4};
    const uint8_t labels[8] = {3, 3, 3, 3, 0, 1, 0, 1};
    double work[32];
    qm_isolation_t iso;
    TEST_ASSERT_EQUAL_INT(MD_OK, qm_isolation_distance(y, 8u, 2u, labels, 3u, NULL, 0u, NULL, NULL, work, 32u, &iso));
    TEST_ASSERT_TRUE(iso.defined);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 24.0, iso.id2);
    /* only 3 non-members for 4 members: undefined, not an error */
    TEST_ASSERT_EQUAL_INT(MD_OK, qm_isolation_distance(y, 7u, 2u, labels, 3u, NULL, 0u, NULL, NULL, work, 32u, &iso));
    TEST_ASSERT_FALSE(iso.defined);
    TEST_ASSERT_EQUAL_size_t(3u, iso.n_nonmembers);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, iso.id2);
    /* two members cannot give a 2-D covariance */
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE,
                          qm_isolation_distance(y, 8u, 2u, labels, 1u, NULL, 0u, NULL, NULL, work, 32u, &iso));
}

static void test_selection_matches_sorting_on_many_points(void)
{
    /* 1-D: members at 0 (var 1 given), 200 non-members at a permuted grid */
    static double y[250];
    static uint8_t labels[250];
    static double work[250];
    for (size_t i = 0u; i < 250u; ++i) {
        labels[i] = (i < 50u) ? 1u : 0u;
        y[i] = (i < 50u) ? 0.0 : (double)((i * 37u) % 200u) + 0.5; /* 37 coprime to 200: a permutation */
    }
    const double mu = 0.0, var = 1.0;
    qm_isolation_t iso;
    TEST_ASSERT_EQUAL_INT(MD_OK, qm_isolation_distance(y, 250u, 1u, labels, 1u, NULL, 0u, &mu, &var, work, 250u, &iso));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 49.5 * 49.5, iso.id2); /* 50th smallest of 0.5, 1.5, ... */
}

static void test_noise_feature_covariance(void)
{
    /* basis rows e0 and e2 in R^4: Ξ is the covariance of samples 0 and 2 */
    pca_basis_t b;
    memset(&b, 0, sizeof b);
    b.d = 2u;
    b.d_w = 4u;
    b.b[0] = 1.0;
    b.b[4 + 2] = 1.0;
    const double noise[4 * STRIDE] = {1, 9, 2, 9, 0, 0, 0, 0,  /* (1, 2) */
                                      3, 9, 2, 9, 0, 0, 0, 0,  /* (3, 2) */
                                      1, 9, 6, 9, 0, 0, 0, 0,  /* (1, 6) */
                                      3, 9, 6, 9, 0, 0, 0, 0}; /* (3, 6) */
    double xi[4];
    TEST_ASSERT_EQUAL_INT(MD_OK, qm_noise_feature_cov(&b, noise, 4u, STRIDE, xi));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 4.0 / 3.0, xi[0]);  /* sum (x-2)^2 = 4, /(m-1) */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 16.0 / 3.0, xi[3]); /* sum (x-4)^2 = 16 */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.0, xi[1]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.0, xi[2]);
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, qm_noise_feature_cov(&b, noise, 2u, STRIDE, xi));
    b.b[4 + 2] = 0.0;
    b.b[4 + 1] = 1.0; /* sample 1 is constant: Ξ singular */
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, qm_noise_feature_cov(&b, noise, 4u, STRIDE, xi));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_noise_rms_and_snr);
    RUN_TEST(test_isolation_distance_given_sigma);
    RUN_TEST(test_isolation_distance_estimated_and_undefined);
    RUN_TEST(test_selection_matches_sorting_on_many_points);
    RUN_TEST(test_noise_feature_covariance);
    return UNITY_END();
}
