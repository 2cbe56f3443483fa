/// Host tests of the fault-injecting bus wrapper (common/bus/md_bus_fault.h)
/// over the in-process bus: each fault kind alone, the windows, the id
/// filter, determinism per seed, parameter validation.
#include <errno.h>
#include <string.h>

#include "md_bus.h"
#include "md_bus_fault.h"
#include "unity.h"

static md_bus_t g_tx_inner, g_rx_inner; /* must not move while open */
static md_bus_fault_t g_fault;

void setUp(void)
{
    memset(&g_tx_inner, 0, sizeof g_tx_inner);
    memset(&g_rx_inner, 0, sizeof g_rx_inner);
    memset(&g_fault, 0, sizeof g_fault);
}

/* Closes whatever the test left open, also when a failed assertion ended it
 * before its own close: an endpoint left open would hold a slot of the
 * process-wide in-process tables for every later test. */
void tearDown(void)
{
    md_bus_t *const eps[] = {&g_fault.bus, &g_tx_inner, &g_rx_inner}; /* the wrapper first */
    for (size_t i = 0; i < sizeof eps / sizeof eps[0]; ++i) {
        if (eps[i]->ops != NULL) { /* NULL: not opened (or wrapped) in this test */
            md_bus_close(eps[i]);
        }
    }
}

static md_frame_t frame_n(uint32_t n)
{
    md_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = 0x300u + (n % 4u);
    f.len = 8u;
    f.data[0] = (uint8_t)(n & 0xFFu);
    f.data[1] = (uint8_t)(n >> 8);
    f.data[2] = 0xA5u;
    return f;
}

static uint32_t frame_no(const md_frame_t *f)
{
    return (uint32_t)f->data[0] | ((uint32_t)f->data[1] << 8);
}

/* Opens sender and receiver on one in-process bus; wraps the side asked. */
static void open_pair(const md_bus_fault_params_t *p, bool wrap_rx, md_bus_t **tx, md_bus_t **rx)
{
    char why[160] = "";
    TEST_ASSERT_EQUAL_INT_MESSAGE(0, md_bus_open(&g_tx_inner, "inproc:fault", why, sizeof why), why);
    TEST_ASSERT_EQUAL_INT_MESSAGE(0, md_bus_open(&g_rx_inner, "inproc:fault", why, sizeof why), why);
    TEST_ASSERT_EQUAL_INT(0, md_bus_fault_wrap(&g_fault, wrap_rx ? &g_rx_inner : &g_tx_inner, p, NULL, NULL));
    *tx = wrap_rx ? &g_tx_inner : &g_fault.bus;
    *rx = wrap_rx ? &g_fault.bus : &g_rx_inner;
}

static void close_pair(void)
{
    md_bus_close(&g_fault.bus); /* closes its inner endpoint */
    md_bus_close(&g_tx_inner);
    md_bus_close(&g_rx_inner);
}

/* Sends n numbered frames, receives everything; returns how many arrived. */
static uint32_t run(md_bus_t *tx, md_bus_t *rx, uint32_t n, md_frame_t *got, uint32_t cap)
{
    for (uint32_t i = 0; i < n; ++i) {
        const md_frame_t f = frame_n(i);
        TEST_ASSERT_EQUAL_INT(0, md_bus_send(tx, &f));
    }
    uint32_t k = 0;
    md_frame_t f;
    while (k < cap && md_bus_receive(rx, &f, 0) == 1) {
        got[k++] = f;
    }
    if (tx == &g_fault.bus) { /* frames still held on the sender side */
        TEST_ASSERT_EQUAL_INT(0, md_bus_fault_flush(&g_fault));
        while (k < cap && md_bus_receive(rx, &f, 0) == 1) {
            got[k++] = f;
        }
    }
    return k;
}

static md_frame_t g_got[4096];

static void test_no_faults_passes_every_frame_in_order(void)
{
    md_bus_fault_params_t p;
    md_bus_fault_default_params(&p);
    md_bus_t *tx, *rx;
    open_pair(&p, false, &tx, &rx);
    TEST_ASSERT_EQUAL_UINT32(200u, run(tx, rx, 200u, g_got, 4096u));
    for (uint32_t i = 0; i < 200u; ++i) {
        TEST_ASSERT_EQUAL_UINT32(i, frame_no(&g_got[i]));
    }
    const md_bus_fault_counters_t c = md_bus_fault_counters(&g_fault);
    TEST_ASSERT_EQUAL_UINT64(200u, c.frames_seen);
    for (uint32_t k = 0; k < MD_BUS_FAULT_KINDS; ++k) {
        TEST_ASSERT_EQUAL_UINT64(0u, c.injected[k]);
    }
    close_pair();
}

static void test_loss_drops_counted_frames_and_is_deterministic(void)
{
    md_bus_fault_params_t p;
    md_bus_fault_default_params(&p);
    p.prob[MD_BUS_FAULT_LOSS] = 0.3;
    p.seed = 42u;
    uint32_t first[1000];
    uint32_t n_first = 0;
    for (int rep = 0; rep < 2; ++rep) {
        md_bus_t *tx, *rx;
        open_pair(&p, false, &tx, &rx);
        const uint32_t n = run(tx, rx, 1000u, g_got, 4096u);
        const md_bus_fault_counters_t c = md_bus_fault_counters(&g_fault);
        TEST_ASSERT_EQUAL_UINT64(1000u - n, c.injected[MD_BUS_FAULT_LOSS]);
        /* binomial(1000, 0.3): mean 300, sd 14.5; +-5 sd */
        TEST_ASSERT_GREATER_OR_EQUAL_UINT(227u, 1000u - n);
        TEST_ASSERT_LESS_OR_EQUAL_UINT(373u, 1000u - n);
        if (rep == 0) {
            n_first = n;
            for (uint32_t i = 0; i < n; ++i) {
                first[i] = frame_no(&g_got[i]);
            }
        } else {
            TEST_ASSERT_EQUAL_UINT32(n_first, n);
            for (uint32_t i = 0; i < n; ++i) {
                TEST_ASSERT_EQUAL_UINT32(first[i], frame_no(&g_got[i]));
            }
        }
        close_pair();
    }
    /* another seed loses other frames */
    p.seed = 43u;
    md_bus_t *tx, *rx;
    open_pair(&p, false, &tx, &rx);
    const uint32_t n = run(tx, rx, 1000u, g_got, 4096u);
    bool differs = (n != n_first);
    for (uint32_t i = 0; i < n && i < n_first && !differs; ++i) {
        differs = first[i] != frame_no(&g_got[i]);
    }
    TEST_ASSERT_TRUE(differs);
    close_pair();
}

static void test_corruption_flips_exactly_one_payload_bit(void)
{
    md_bus_fault_params_t p;
    md_bus_fault_default_params(&p);
    p.prob[MD_BUS_FAULT_CORRUPT] = 1.0;
    md_bus_t *tx, *rx;
    open_pair(&p, false, &tx, &rx);
    TEST_ASSERT_EQUAL_UINT32(100u, run(tx, rx, 100u, g_got, 4096u));
    for (uint32_t i = 0; i < 100u; ++i) {
        const md_frame_t want = frame_n(i);
        TEST_ASSERT_EQUAL_UINT32(want.id, g_got[i].id);
        TEST_ASSERT_EQUAL_UINT8(want.len, g_got[i].len);
        uint32_t bits = 0;
        for (uint32_t b = 0; b < want.len; ++b) {
            bits += (uint32_t)__builtin_popcount((unsigned)(want.data[b] ^ g_got[i].data[b]));
        }
        TEST_ASSERT_EQUAL_UINT32(1u, bits);
    }
    TEST_ASSERT_EQUAL_UINT64(100u, md_bus_fault_counters(&g_fault).injected[MD_BUS_FAULT_CORRUPT]);
    close_pair();
}

static void test_duplication_sends_each_frame_twice(void)
{
    md_bus_fault_params_t p;
    md_bus_fault_default_params(&p);
    p.prob[MD_BUS_FAULT_DUP] = 1.0;
    md_bus_t *tx, *rx;
    open_pair(&p, false, &tx, &rx);
    TEST_ASSERT_EQUAL_UINT32(100u, run(tx, rx, 50u, g_got, 4096u));
    for (uint32_t i = 0; i < 50u; ++i) {
        TEST_ASSERT_EQUAL_UINT32(i, frame_no(&g_got[2u * i]));
        TEST_ASSERT_EQUAL_UINT32(i, frame_no(&g_got[2u * i + 1u]));
    }
    TEST_ASSERT_EQUAL_UINT64(50u, md_bus_fault_counters(&g_fault).injected[MD_BUS_FAULT_DUP]);
    close_pair();
}

static void test_delay_releases_after_n_frames_inside_the_frame_window(void)
{
    md_bus_fault_params_t p;
    md_bus_fault_default_params(&p);
    p.prob[MD_BUS_FAULT_DELAY] = 1.0;
    p.delay_frames = 3u;
    p.frame_from = 2u; /* only frame 2 */
    p.frame_to = 3u;
    md_bus_t *tx, *rx;
    open_pair(&p, false, &tx, &rx);
    TEST_ASSERT_EQUAL_UINT32(8u, run(tx, rx, 8u, g_got, 4096u));
    static const uint32_t want[8] = {0, 1, 3, 4, 5, 2, 6, 7};
    for (uint32_t i = 0; i < 8u; ++i) {
        TEST_ASSERT_EQUAL_UINT32(want[i], frame_no(&g_got[i]));
    }
    TEST_ASSERT_EQUAL_UINT64(1u, md_bus_fault_counters(&g_fault).injected[MD_BUS_FAULT_DELAY]);
    close_pair();
}

static void test_reorder_swaps_consecutive_frames(void)
{
    md_bus_fault_params_t p;
    md_bus_fault_default_params(&p);
    p.prob[MD_BUS_FAULT_REORDER] = 1.0;
    p.frame_from = 4u;
    p.frame_to = 5u;
    md_bus_t *tx, *rx;
    open_pair(&p, false, &tx, &rx);
    TEST_ASSERT_EQUAL_UINT32(7u, run(tx, rx, 7u, g_got, 4096u));
    static const uint32_t want[7] = {0, 1, 2, 3, 5, 4, 6};
    for (uint32_t i = 0; i < 7u; ++i) {
        TEST_ASSERT_EQUAL_UINT32(want[i], frame_no(&g_got[i]));
    }
    TEST_ASSERT_EQUAL_UINT64(1u, md_bus_fault_counters(&g_fault).injected[MD_BUS_FAULT_REORDER]);
    close_pair();
}

static void test_receive_side_loss_and_idle_release_of_delayed_frames(void)
{
    md_bus_fault_params_t p;
    md_bus_fault_default_params(&p);
    p.directions = MD_BUS_FAULT_RX;
    p.prob[MD_BUS_FAULT_LOSS] = 1.0;
    p.frame_from = 0u;
    p.frame_to = 2u; /* the first two received frames are lost */
    md_bus_t *tx, *rx;
    open_pair(&p, true, &tx, &rx);
    TEST_ASSERT_EQUAL_UINT32(3u, run(tx, rx, 5u, g_got, 4096u));
    TEST_ASSERT_EQUAL_UINT32(2u, frame_no(&g_got[0]));
    TEST_ASSERT_EQUAL_UINT64(2u, md_bus_fault_counters(&g_fault).injected[MD_BUS_FAULT_LOSS]);
    close_pair();

    /* a delayed frame with no traffic after it arrives when the bus is idle */
    md_bus_fault_default_params(&p);
    p.directions = MD_BUS_FAULT_RX;
    p.prob[MD_BUS_FAULT_DELAY] = 1.0;
    p.delay_frames = 10u;
    open_pair(&p, true, &tx, &rx);
    TEST_ASSERT_EQUAL_UINT32(3u, run(tx, rx, 3u, g_got, 4096u));
    for (uint32_t i = 0; i < 3u; ++i) {
        TEST_ASSERT_EQUAL_UINT32(i, frame_no(&g_got[i]));
    }
    TEST_ASSERT_EQUAL_UINT64(3u, md_bus_fault_counters(&g_fault).injected[MD_BUS_FAULT_DELAY]);
    close_pair();
}

static int64_t g_clock_us;
static int64_t test_clock(void *ctx)
{
    (void)ctx;
    return g_clock_us;
}

static void test_time_window_and_id_filter(void)
{
    md_bus_fault_params_t p;
    md_bus_fault_default_params(&p);
    p.prob[MD_BUS_FAULT_LOSS] = 1.0;
    p.t_from_us = 1000;
    p.t_to_us = 2000;
    p.id_mask = 0x7FFu;
    p.id_match = 0x301u; /* frame_n(1), (5), (9)...: only those */
    char why[160] = "";
    TEST_ASSERT_EQUAL_INT_MESSAGE(0, md_bus_open(&g_tx_inner, "inproc:fault", why, sizeof why), why);
    TEST_ASSERT_EQUAL_INT_MESSAGE(0, md_bus_open(&g_rx_inner, "inproc:fault", why, sizeof why), why);
    TEST_ASSERT_EQUAL_INT(0, md_bus_fault_wrap(&g_fault, &g_tx_inner, &p, test_clock, NULL));
    uint32_t sent = 0;
    for (int64_t t = 0; t < 3000; t += 500) { /* 6 time slots x 8 frames */
        g_clock_us = t;
        for (uint32_t i = 0; i < 8u; ++i, ++sent) {
            const md_frame_t f = frame_n(sent);
            TEST_ASSERT_EQUAL_INT(0, md_bus_send(&g_fault.bus, &f));
        }
    }
    uint32_t k = 0;
    md_frame_t f;
    while (md_bus_receive(&g_rx_inner, &f, 0) == 1) {
        const uint32_t n = frame_no(&f);
        const int64_t t = (int64_t)(n / 8u) * 500;
        TEST_ASSERT_FALSE(f.id == 0x301u && t >= 1000 && t < 2000);
        k++;
    }
    /* slots 1000 and 1500: 2 frames with id 0x301 in each */
    TEST_ASSERT_EQUAL_UINT32(48u - 4u, k);
    TEST_ASSERT_EQUAL_UINT64(4u, md_bus_fault_counters(&g_fault).injected[MD_BUS_FAULT_LOSS]);
    close_pair();
}

static void test_bad_parameters_are_refused(void)
{
    md_bus_fault_params_t p;
    md_bus_fault_default_params(&p);
    char why[160] = "";
    TEST_ASSERT_EQUAL_INT_MESSAGE(0, md_bus_open(&g_tx_inner, "inproc:fault", why, sizeof why), why);
    p.prob[MD_BUS_FAULT_LOSS] = 1.5;
    TEST_ASSERT_EQUAL_INT(-EINVAL, md_bus_fault_wrap(&g_fault, &g_tx_inner, &p, NULL, NULL));
    p.prob[MD_BUS_FAULT_LOSS] = 0.6;
    p.prob[MD_BUS_FAULT_DUP] = 0.6; /* sum above 1 */
    TEST_ASSERT_EQUAL_INT(-EINVAL, md_bus_fault_wrap(&g_fault, &g_tx_inner, &p, NULL, NULL));
    md_bus_fault_default_params(&p);
    p.delay_frames = 0u;
    TEST_ASSERT_EQUAL_INT(-EINVAL, md_bus_fault_wrap(&g_fault, &g_tx_inner, &p, NULL, NULL));
    p.delay_frames = MD_BUS_FAULT_HOLD_MAX + 1u;
    TEST_ASSERT_EQUAL_INT(-EINVAL, md_bus_fault_wrap(&g_fault, &g_tx_inner, &p, NULL, NULL));
    md_bus_fault_default_params(&p);
    TEST_ASSERT_EQUAL_INT(-EINVAL, md_bus_fault_wrap(&g_fault, NULL, &p, NULL, NULL));
    TEST_ASSERT_EQUAL_STRING("reorder", md_bus_fault_kind_name(MD_BUS_FAULT_REORDER));
    md_bus_close(&g_tx_inner);
}

static void test_full_hold_queue_passes_frames_and_counts(void)
{
    md_bus_fault_params_t p;
    md_bus_fault_default_params(&p);
    p.prob[MD_BUS_FAULT_DELAY] = 1.0;
    p.delay_frames = MD_BUS_FAULT_HOLD_MAX;
    md_bus_t *tx, *rx;
    open_pair(&p, false, &tx, &rx);
    const uint32_t n = MD_BUS_FAULT_HOLD_MAX + 5u;
    TEST_ASSERT_EQUAL_UINT32(n, run(tx, rx, n, g_got, 4096u)); /* nothing lost */
    const md_bus_fault_counters_t c = md_bus_fault_counters(&g_fault);
    TEST_ASSERT_EQUAL_UINT64(n, c.injected[MD_BUS_FAULT_DELAY] + c.hold_full);
    TEST_ASSERT_GREATER_THAN_UINT(0u, (unsigned)c.hold_full);
    close_pair();
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_no_faults_passes_every_frame_in_order);
    RUN_TEST(test_loss_drops_counted_frames_and_is_deterministic);
    RUN_TEST(test_corruption_flips_exactly_one_payload_bit);
    RUN_TEST(test_duplication_sends_each_frame_twice);
    RUN_TEST(test_delay_releases_after_n_frames_inside_the_frame_window);
    RUN_TEST(test_reorder_swaps_consecutive_frames);
    RUN_TEST(test_receive_side_loss_and_idle_release_of_delayed_frames);
    RUN_TEST(test_time_window_and_id_filter);
    RUN_TEST(test_bad_parameters_are_refused);
    RUN_TEST(test_full_hold_queue_passes_frames_and_counts);
    return UNITY_END();
}
