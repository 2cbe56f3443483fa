/// @file test_approach_guard.c
/// Approach guard on scripted amplitude sequences: a neuron on the path
/// (steep growth), a new track rising under a louder unit, a neuron passed at a safe lateral distance (shallow
/// growth), noise, a unit that climbs while the electrode stands (fast, or
/// creeping slowly as relaxing tissue carries it), artefact
/// bursts that must not freeze the search, amp_stop, the depth fence, the
/// tissue's give-back after an advance, invalid input, and the robust
/// amplitude itself.
#include <math.h>
#include <string.h>

#include "control/approach_guard.h"
#include "unity.h"

static ag_state_t g;
static ag_config_t cfg;
static double clock_s; /* the latest interval's time */

void setUp(void)
{
    clock_s = 0.0;
    ag_config_default(&cfg);
    TEST_ASSERT_EQUAL_INT(MD_OK, ag_init(&g, &cfg));
}

void tearDown(void) {}

/* The amplitude law A(d) = a0 / (1 + d^2 / d0^2), in noise RMS units, plus
 * the noise floor of a peak-to-peak measure. */
static double law(double a0, double r_um, double x_um)
{
    return 3.0 + a0 / (1.0 + (r_um * r_um + x_um * x_um) / 900.0);
}

/* Intervals are 10 s apart. */
static double next_time(void)
{
    clock_s += 10.0;
    return clock_s;
}

/* One interval with the robust amplitude only. */
static ag_output_t step1(double amp, double depth, double want)
{
    const ag_unit_t u = {AG_UNIT_RAW, amp};
    const ag_input_t in = {&u, 1u, depth, next_time(), want, false};
    ag_output_t out;
    TEST_ASSERT_EQUAL_INT(MD_OK, ag_apply(&g, &in, &out));
    return out;
}

/* Advances by what the SFSM asks (20 µm) as far as the guard lets it, towards
 * a unit at depth 200 and lateral distance r; returns the closest distance. */
static double approach(double a0, double r_um, int cycles)
{
    double z = 0.0;
    double closest = HUGE_VAL;
    for (int k = 0; k < cycles; ++k) {
        const double x = 200.0 - z;
        closest = fmin(closest, hypot(r_um, x));
        const ag_output_t out = step1(law(a0, r_um, x), z, 20.0);
        TEST_ASSERT_TRUE(out.move_um <= 20.0);
        z += out.move_um;
    }
    return closest;
}

/* Advances towards an 80-noise-RMS neuron on the path until it gets a
 * ceiling; returns the depth reached. */
static double approach_until_ceiling(void)
{
    double z = 0.0;
    for (int k = 0; k < 40 && g.n_ceil == 0u; ++k) {
        z += step1(law(80.0, 0.0, 200.0 - z), z, 20.0).move_um;
    }
    TEST_ASSERT_EQUAL_UINT8(1u, g.n_ceil);
    return z;
}

static void test_a_neuron_on_the_path_is_never_reached(void)
{
    /* On the path (r = 0) the tip would kill it within 12 µm. Contact
     * amplitudes from 40 noise RMS up: a smaller neuron reaches amp_floor only
     * inside the damage radius (docs/sfsm.md, "Approach guard", limits). */
    for (double a0 = 40.0; a0 <= 120.0; a0 += 20.0) {
        setUp();
        const double closest = approach(a0, 0.0, 60);
        TEST_ASSERT_TRUE_MESSAGE(closest > 12.0, "the tip came within the damage radius");
        TEST_ASSERT_TRUE(g.n_ceil >= 1u);
    }
}

static void test_a_neuron_passed_at_a_safe_distance_does_not_stop_the_advance(void)
{
    /* 45 µm off the track: growth never reaches growth_stop twice in a row. */
    approach(60.0, 45.0, 30);
    TEST_ASSERT_EQUAL_UINT8(0u, g.n_ceil);
    TEST_ASSERT_EQUAL_UINT32(0u, g.ceilings_set);
}

static void test_advances_are_shortened_while_a_loud_unit_may_be_ahead(void)
{
    ag_output_t out = step1(cfg.amp_slow - 5.0, 0.0, 30.0);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 30.0, out.move_um);
    TEST_ASSERT_EQUAL_INT(AG_PASS, out.action);
    out = step1(cfg.amp_slow + 1.0, 30.0, 30.0); /* grew by ln(16 / 10) / 30 µm: ahead */
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, cfg.move_near_um, out.move_um);
    TEST_ASSERT_EQUAL_INT(AG_SLOWED, out.action);
    out = step1(cfg.amp_slow + 1.0, 40.0, -30.0); /* retractions are never shortened */
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, -30.0, out.move_um);
    setUp();
    out = step1(cfg.amp_slow + 1.0, 0.0, 30.0); /* first interval: its growth is not known */
    TEST_ASSERT_EQUAL_INT(AG_SLOWED, out.action);
}

/* One interval with the robust amplitude and one track. */
static ag_output_t step2(double raw, uint32_t id, double amp, double depth, double want)
{
    const ag_unit_t u[2] = {{AG_UNIT_RAW, raw}, {id, amp}};
    const ag_input_t in = {u, (amp > 0.0) ? 2u : 1u, depth, next_time(), want, false};
    ag_output_t out;
    TEST_ASSERT_EQUAL_INT(MD_OK, ag_apply(&g, &in, &out));
    return out;
}

/* A track born one 10 µm step ago, under a louder flat unit, rising by
 * `growth` per µm on the next step; returns that interval's output. */
static ag_output_t new_track_rising(double growth)
{
    step2(30.0, 0u, 0.0, 0.0, 10.0);
    step2(30.0, 7u, 16.0, 10.0, 10.0);
    return step2(30.0, 7u, 16.0 * exp(growth * 10.0), 20.0, 20.0);
}

static void test_a_new_track_rising_faster_than_any_neuron_beside_the_track_gets_a_ceiling(void)
{
    /* Its only history is one step, shorter than baseline_min_um: the
     * short baseline judges it, from growth_max on. */
    const ag_output_t out = new_track_rising(cfg.growth_max * 1.08);
    TEST_ASSERT_EQUAL_UINT8(1u, g.n_ceil);
    TEST_ASSERT_EQUAL_UINT32(7u, g.ceil[0].id);
    TEST_ASSERT_EQUAL_INT(AG_BLOCKED, out.action);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 0.0, out.move_um);
}

static void test_a_new_track_rising_like_a_neuron_beside_the_track_only_slows(void)
{
    /* Between growth_stop and growth_max over the short baseline: what a
     * neuron 25 µm beside the track reads when its track is born. No
     * ceiling, and rule 5 still counts its growth unmeasured. */
    const ag_output_t out = new_track_rising(0.5 * (cfg.growth_stop + cfg.growth_max));
    TEST_ASSERT_EQUAL_UINT8(0u, g.n_ceil);
    TEST_ASSERT_EQUAL_INT(AG_SLOWED, out.action);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, cfg.move_near_um, out.move_um);
    setUp();
    const ag_output_t flat = new_track_rising(0.0);
    TEST_ASSERT_EQUAL_INT(AG_SLOWED, flat.action);
}

static void test_a_loud_unit_beside_the_tip_does_not_slow_the_search(void)
{
    /* Passing a neuron 25 µm off the track at its depth: loud, but its
     * amplitude hardly changes over an advance. */
    step1(law(60.0, 25.0, 10.0), 0.0, cfg.move_near_um);
    const ag_output_t out = step1(law(60.0, 25.0, -10.0), 20.0, 20.0);
    TEST_ASSERT_TRUE(law(60.0, 25.0, -10.0) >= cfg.amp_slow);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 20.0, out.move_um);
    TEST_ASSERT_EQUAL_INT(AG_PASS, out.action);
}

static void test_noise_at_a_standstill_never_retracts(void)
{
    /* ±8 % noise around a loud unit, standing still for 200 intervals. */
    uint32_t x = 12345u;
    for (int k = 0; k < 200; ++k) {
        x = x * 1103515245u + 12345u;
        const double noise = ((double)(x >> 16 & 0x7FFFu) / 32767.0 - 0.5) * 0.16;
        const ag_output_t out = step1(30.0 * (1.0 + noise), 100.0, 0.0);
        TEST_ASSERT_EQUAL_INT(AG_PASS, out.action);
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, 0.0, out.move_um);
    }
    TEST_ASSERT_EQUAL_UINT32(0u, g.retractions);
}

static void test_a_unit_climbing_at_a_standstill_makes_the_electrode_give_way(void)
{
    /* A quieter unit (a track) climbs while a louder one stays: the robust
     * amplitude alone would not show it. */
    double z = 100.0;
    int retractions = 0;
    for (int k = 0; k < 30; ++k) {
        const ag_unit_t u[2] = {{AG_UNIT_RAW, 40.0}, {7u, 16.0 * pow(1.05, k)}};
        const ag_input_t in = {u, 2u, z, next_time(), 0.0, false};
        ag_output_t out;
        TEST_ASSERT_EQUAL_INT(MD_OK, ag_apply(&g, &in, &out));
        if (out.action == AG_RETRACT) {
            TEST_ASSERT_DOUBLE_WITHIN(1e-9, -cfg.retract_um, out.move_um);
            retractions++;
        }
        z += out.move_um;
    }
    TEST_ASSERT_TRUE(retractions >= 1);
    TEST_ASSERT_TRUE(z < 100.0);
}

static void test_a_slow_creep_towards_a_standing_tip_adds_up_to_a_retraction(void)
{
    /* Relaxing tissue carries a neuron 0.3 µm per interval towards the tip,
     * which stands 22 µm away: each interval's rise (~1 %) hides in noise of
     * a few per cent, the sum must not. The tip must give way before the
     * damage radius (12 µm) with a margin. */
    double z = 100.0;
    double soma = 122.0;
    double closest = HUGE_VAL;
    uint32_t x = 12345u;
    for (int k = 0; k < 120; ++k) {
        x = x * 1103515245u + 12345u;
        const double noise = ((double)(x >> 16 & 0x7FFFu) / 32767.0 - 0.5) * 0.08;
        closest = fmin(closest, hypot(6.0, soma - z));
        const ag_output_t out = step1(law(50.0, 6.0, soma - z) * (1.0 + noise), z, 0.0);
        TEST_ASSERT_TRUE(out.move_um <= 0.0);
        z += out.move_um;
        soma -= 0.3;
    }
    TEST_ASSERT_TRUE(g.retractions >= 1u);
    TEST_ASSERT_TRUE(closest > 15.0);
}

/* Rules 6 alone: the tissue gives nothing back. */
static void without_tissue_give_back(void)
{
    cfg.relax_frac = 1e-9;
    TEST_ASSERT_EQUAL_INT(MD_OK, ag_init(&g, &cfg));
}

/* A fence at depth z, as a retraction there would leave it. */
static void put_fence_for_test(double z)
{
    g.fence_um = z;
    g.fence_amp = 0.0;
}

static void test_a_unit_saturating_at_its_ceiling_holds_the_electrode(void)
{
    /* The tissue settled; the neuron stays where it is, the SFSM keeps asking
     * for 10 µm: the tip holds at the fence, without retracting. */
    without_tissue_give_back();
    const double z = approach_until_ceiling();
    const double ceiling = g.ceil[0].amp;
    for (int k = 0; k < 50; ++k) {
        const ag_output_t out = step1(ceiling, z, 10.0);
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, 0.0, out.move_um);
        TEST_ASSERT_EQUAL_INT(AG_BLOCKED, out.action);
    }
    TEST_ASSERT_EQUAL_UINT32(0u, g.retractions);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, z, g.fence_um);
}

static void test_a_neuron_drifting_onto_a_tip_at_its_ceiling_is_given_way(void)
{
    /* Near the soma A(d) is flat: a neuron 6 µm off the track that got its
     * ceiling 17 µm from the tip grows by only ~14 % as it drifts to the
     * damage radius (3 µm per minute). A smaller climb over the ceiling must
     * retract the tip first. */
    without_tissue_give_back();
    const double z = 100.0;
    double soma = z + sqrt(17.0 * 17.0 - 36.0);
    g.ceil[0] = (ag_ceiling_t){AG_UNIT_RAW, law(60.0, 6.0, soma - z), cfg.growth_stop, z, 0.0, 0u};
    g.n_ceil = 1u;
    double closest = HUGE_VAL;
    for (int k = 0; k < 120 && g.retractions == 0u; ++k) {
        closest = fmin(closest, hypot(6.0, soma - z));
        step1(law(60.0, 6.0, soma - z), z, 0.0);
        soma -= 0.5;
    }
    TEST_ASSERT_EQUAL_UINT32(1u, g.retractions);
    TEST_ASSERT_TRUE_MESSAGE(closest > 12.0, "the tip came within the damage radius");
}

static void test_the_give_back_of_an_advance_retracts_before_it_comes(void)
{
    /* After a descent part of every advance is still to come back towards
     * the tip: a unit at its ceiling would pass it by climb_frac once it has
     * come, so the tip gives way now, and may not return. */
    const double z = approach_until_ceiling();
    const uint32_t before = g.creep_retractions;
    TEST_ASSERT_TRUE(g.pending_um > 0.0);
    const ag_output_t out = step1(g.ceil[0].amp, z, 0.0);
    TEST_ASSERT_EQUAL_INT(AG_RETRACT, out.action);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, -cfg.retract_um, out.move_um);
    TEST_ASSERT_EQUAL_UINT32(before + 1u, g.creep_retractions);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, z - cfg.retract_um, out.fence_um);
}

/* The tissue's give-back over one 10 s interval (time constant 120 s), taken
 * from what is still to come. */
static double give_back_over_an_interval(double *to_come)
{
    const double back = *to_come * (1.0 - exp(-10.0 / 120.0));
    *to_come -= back;
    return back;
}

static void test_a_neuron_on_the_path_in_relaxing_tissue_is_never_reached(void)
{
    /* Each advance drags the tissue 30 % of the way along and 24 % of it
     * comes back towards the tip with a time constant of 120 s: the neuron
     * keeps approaching after the tip stopped. */
    double z = 0.0;
    double soma = 200.0;
    double give_back = 0.0;
    double closest = HUGE_VAL;
    for (int k = 0; k < 150; ++k) {
        soma -= give_back_over_an_interval(&give_back);
        closest = fmin(closest, soma - z);
        const ag_output_t out = step1(law(80.0, 0.0, soma - z), z, 20.0);
        z += out.move_um;
        soma += (out.move_um > 0.0) ? 0.30 * out.move_um : 0.0;
        give_back += (out.move_um > 0.0) ? 0.24 * out.move_um : 0.0;
    }
    TEST_ASSERT_TRUE_MESSAGE(closest > 12.0, "the tip came within the damage radius");
}

/* Stands 17 µm above a faint neuron on the path whose ceiling was set there
 * with `pending` µm of the tissue's give-back still to come; returns the
 * closest distance over 60 intervals. */
static double stand_over_a_ceiling_while_the_tissue_gives_back(double pending)
{
    double z = 100.0;
    double soma = z + 17.0;
    g.pending_um = pending;
    g.ceil[0] = (ag_ceiling_t){AG_UNIT_RAW, law(30.0, 0.0, 17.0), cfg.growth_stop, z, pending, 0u};
    g.n_ceil = 1u;
    double closest = HUGE_VAL;
    for (int k = 0; k < 60; ++k) {
        soma -= give_back_over_an_interval(&pending);
        closest = fmin(closest, soma - z);
        z += step1(law(30.0, 0.0, soma - z), z, 0.0).move_um;
    }
    return closest;
}

static void test_a_ceiling_set_near_the_soma_gives_way_as_the_tissue_gives_back(void)
{
    /* After a descent 12 µm of give-back are to come, more than the room the
     * ceiling left; near the soma the amplitude hardly grows (+9 % from 17 to
     * 12 µm), so the tip must follow the give-back, not the amplitude. */
    const double closest = stand_over_a_ceiling_while_the_tissue_gives_back(12.0);
    TEST_ASSERT_TRUE_MESSAGE(closest > 15.0, "the tip did not give way");
    TEST_ASSERT_TRUE(g.retractions >= 1u);
    setUp();
    stand_over_a_ceiling_while_the_tissue_gives_back(0.0); /* settled tissue: the tip stays */
    TEST_ASSERT_EQUAL_UINT32(0u, g.retractions);
}

static void test_the_fence_follows_a_unit_that_moves_away(void)
{
    without_tissue_give_back();
    const double z = approach_until_ceiling();
    const double ceiling = g.ceil[0].amp;
    for (int k = 0; k < 8; ++k) { /* at the fence: its level is taken */
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, 0.0, step1(ceiling, z, 10.0).move_um);
    }
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, ceiling, g.fence_amp);
    g.probe_barred = true; /* as after a steep probe: only the fall moves the fence */
    const double fence = g.fence_um;
    ag_output_t out = {0};
    for (int k = 0; k < 8 && !(out.move_um > 0.0); ++k) { /* the unit drifted away */
        out = step1(0.8 * ceiling, z, 10.0);
    }
    /* The fence moves once the six-interval level fell by fence_drop_frac,
     * by the least distance that fall needs: less than the whole fall. */
    const double receded = g.fence_um - fence;
    TEST_ASSERT_EQUAL_UINT32(1u, g.fence_moves);
    TEST_ASSERT_TRUE(receded >= log(1.0 / (1.0 - cfg.fence_drop_frac)) / cfg.growth_max - 1e-9);
    TEST_ASSERT_TRUE(receded <= log(1.0 / 0.8) / cfg.growth_max + 1e-9);
    TEST_ASSERT_TRUE(out.move_um > 0.0);
    TEST_ASSERT_TRUE(out.move_um <= receded + 1e-9);
}

static void test_the_fence_holds_when_a_ceiling_lapses(void)
{
    /* A sparse neuron on the path, seen as track 7, sets a ceiling, then
     * goes unseen for longer than a ceiling lasts; a quieter unit keeps the
     * robust amplitude above amp_floor: something is near, the fence stays. */
    without_tissue_give_back();
    double z = 0.0;
    for (int k = 0; k < 40 && g.n_ceil == 0u; ++k) {
        const ag_unit_t u[2] = {{AG_UNIT_RAW, 13.0}, {7u, law(80.0, 0.0, 200.0 - z)}};
        const ag_input_t in = {u, 2u, z, next_time(), 20.0, false};
        ag_output_t out;
        TEST_ASSERT_EQUAL_INT(MD_OK, ag_apply(&g, &in, &out));
        z += out.move_um;
    }
    TEST_ASSERT_EQUAL_UINT8(1u, g.n_ceil);
    for (int k = 0; k < (int)AG_HISTORY + 10; ++k) {
        const ag_output_t out = step1(13.0, z, 20.0);
        TEST_ASSERT_TRUE(z + out.move_um <= g.fence_um + 1e-9);
        z += out.move_um;
    }
    TEST_ASSERT_EQUAL_UINT8(0u, g.n_ceil);
    TEST_ASSERT_FALSE(isinf(g.fence_um));
    TEST_ASSERT_TRUE(200.0 - z > 12.0);
}

/* Stands at the fence while the SFSM asks for 10 µm, the unit at lateral
 * distance r and depth 200 (amplitude law, no give-back) until `cycles`
 * intervals passed; returns the depth reached. */
static double stand_at_fence(double r_um, double z, int cycles)
{
    for (int k = 0; k < cycles; ++k) {
        const ag_output_t out = step1(law(80.0, r_um, 200.0 - z), z, 10.0);
        TEST_ASSERT_TRUE(z + out.move_um <= g.fence_um + 1e-9 || out.action == AG_RETRACT);
        z += out.move_um;
    }
    return z;
}

static void test_a_probe_past_the_fence_finds_the_neuron_beside_the_track(void)
{
    /* A fence 40 µm above the depth of a neuron 30 µm off the track: it grows
     * little over a probe, so the fence moves on probe by probe. */
    without_tissue_give_back();
    put_fence_for_test(160.0);
    const double z = stand_at_fence(30.0, 160.0, 60);
    TEST_ASSERT_TRUE(g.probes >= 3u);
    TEST_ASSERT_EQUAL_UINT32(0u, g.probes_steep);
    TEST_ASSERT_TRUE(z >= 160.0 + 3.0 * cfg.probe_um - 1e-9);
}

static void test_a_probe_towards_a_neuron_on_the_path_goes_back(void)
{
    /* The same fence 25 µm above a neuron on the path: the probe is steep,
     * the tip goes back to the fence and probes no more. */
    without_tissue_give_back();
    put_fence_for_test(175.0);
    const double z = stand_at_fence(0.0, 175.0, 60);
    TEST_ASSERT_EQUAL_UINT32(1u, g.probes);
    TEST_ASSERT_EQUAL_UINT32(1u, g.probes_steep);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 175.0, g.fence_um);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 175.0, z);
}

static void test_an_artefact_burst_does_not_freeze_the_search(void)
{
    /* Three intervals of huge artefacts on a track unit set a ceiling and a
     * fence; when they end only noise is left (below amp_floor): the ceiling
     * lapses, then the fence, and the advance goes on. */
    double z = 0.0;
    for (int k = 0; k < 3; ++k) {
        const ag_unit_t u[2] = {{AG_UNIT_RAW, 9.0}, {3u, 20.0 * pow(3.0, k)}};
        const ag_input_t in = {u, 2u, z, next_time(), 20.0, false};
        ag_output_t out;
        TEST_ASSERT_EQUAL_INT(MD_OK, ag_apply(&g, &in, &out));
        z += out.move_um;
    }
    TEST_ASSERT_FALSE(isinf(g.fence_um));
    for (int k = 0; k < (int)cfg.fence_lapse + 2; ++k) {
        z += step1(9.0, z, 20.0).move_um;
    }
    TEST_ASSERT_EQUAL_UINT8(0u, g.n_ceil);
    TEST_ASSERT_TRUE(isinf(g.fence_um));
    TEST_ASSERT_EQUAL_UINT32(1u, g.fence_lapses);
    const ag_output_t out = step1(9.0, z, 20.0);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 20.0, out.move_um);
}

static void test_amp_stop_is_a_ceiling_for_every_unit(void)
{
    ag_output_t out = step1(cfg.amp_stop, 0.0, 5.0);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 0.0, out.move_um);
    TEST_ASSERT_EQUAL_INT(AG_BLOCKED, out.action);
    setUp();
    out = step1(cfg.amp_stop * 0.9, 0.0, 30.0);
    TEST_ASSERT_TRUE(out.move_um > 0.0 && out.move_um <= log(1.0 / 0.9) / cfg.growth_stop + 1e-9);
}

/* Rule 8: in active tissue no advance leaves more than pace_um of give-back
 * to come, and the search still moves on as it comes back; in quiet tissue,
 * with pace 0, and for retractions nothing changes. */
static void test_the_pace_bounds_the_give_back_still_to_come(void)
{
    cfg.pace_um = 10.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, ag_init(&g, &cfg));
    double z = 0.0;
    for (int k = 0; k < 30; ++k) {
        const ag_output_t out = step1(cfg.amp_floor + 1.0, z, 20.0);
        TEST_ASSERT_TRUE(out.move_um >= 0.0);
        TEST_ASSERT_TRUE(g.pending_um + cfg.relax_frac * out.move_um <= cfg.pace_um + 1e-9);
        TEST_ASSERT_TRUE(!(out.move_um > 0.0) || out.move_um >= cfg.still_um); /* no creeping steps */
        z += out.move_um;
    }
    /* 10 µm of give-back leaves 0.8 µm per 10 s interval: ~3.3 µm of advance */
    TEST_ASSERT_TRUE(z > 60.0 && z < 150.0);
    const ag_output_t back = step1(cfg.amp_floor + 1.0, z, -20.0);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, -20.0, back.move_um);
    setUp(); /* quiet tissue: below amp_floor nothing is heard that could be masked */
    cfg.pace_um = 10.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, ag_init(&g, &cfg));
    for (int k = 0; k < 5; ++k) {
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, 20.0, step1(cfg.amp_floor - 1.0, 20.0 * k, 20.0).move_um);
    }
    setUp(); /* pace 0: off */
    for (int k = 0; k < 5; ++k) {
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, 20.0, step1(cfg.amp_floor + 1.0, 20.0 * k, 20.0).move_um);
    }
}

/* The tissue counts as settled once its give-back still to come is at most
 * settle_um: not after a descent, again after standing a few time constants. */
static void test_the_tissue_settles_after_the_give_back(void)
{
    TEST_ASSERT_TRUE(ag_settled(&g));
    for (int k = 0; k < 5; ++k) {
        (void)step1(cfg.amp_floor - 1.0, 20.0 * k, 20.0);
    }
    TEST_ASSERT_FALSE(ag_settled(&g));
    const double due = g.pending_um;
    int waited = 0;
    while (!ag_settled(&g) && waited < 200) {
        (void)step1(cfg.amp_floor - 1.0, 80.0, 0.0);
        waited++;
    }
    TEST_ASSERT_TRUE(ag_settled(&g));
    /* due × e^(-10 n / 120) <= settle_um */
    TEST_ASSERT_INT_WITHIN(1, (int)ceil(120.0 / 10.0 * log(due / cfg.settle_um)), waited);
    TEST_ASSERT_FALSE(ag_settled(NULL));
}

/* One interval with the robust amplitude only, the SFSM holding a lone
 * neuron or not. */
static ag_output_t step_lone(double amp, double depth, double want, bool lone)
{
    const ag_unit_t u = {AG_UNIT_RAW, amp};
    const ag_input_t in = {&u, 1u, depth, next_time(), want, lone};
    ag_output_t out;
    TEST_ASSERT_EQUAL_INT(MD_OK, ag_apply(&g, &in, &out));
    return out;
}

/* Rule 9: after a descent past a loud unit the standing tip retracts by the
 * give-back as it comes, in steps of at least still_um, and reaches where the model puts it
 * even when the servo stops short of each retraction; a tip beside a lone
 * neuron stands. */
static void follow_after_a_descent(double executed_share, bool lone, double *retracted, double *came)
{
    cfg.follow = true;
    TEST_ASSERT_EQUAL_INT(MD_OK, ag_init(&g, &cfg));
    double z = 0.0;
    for (int k = 0; k < 8; ++k) { /* a loud unit that does not grow: no ceiling */
        z += step_lone(cfg.amp_slow + 1.0, z, 20.0, lone).move_um;
    }
    TEST_ASSERT_TRUE(z > 100.0);
    TEST_ASSERT_EQUAL_UINT8(0u, g.n_ceil);
    const double stop = z;
    (void)step_lone(cfg.amp_slow + 1.0, z, 0.0, lone); /* the tip stands from here */
    const double due = g.pending_um;
    for (int k = 0; k < 40; ++k) {
        const ag_output_t out = step_lone(cfg.amp_slow + 1.0, z, 0.0, lone);
        TEST_ASSERT_TRUE(out.move_um <= 0.0);
        TEST_ASSERT_TRUE(!(out.move_um < 0.0) || out.move_um <= -cfg.still_um + 1e-9);
        z += executed_share * out.move_um;
    }
    *retracted = stop - z;
    *came = due - g.pending_um;
}

static void test_a_standing_tip_follows_the_give_back(void)
{
    double retracted = 0.0;
    double came = 0.0;
    follow_after_a_descent(1.0, false, &retracted, &came);
    TEST_ASSERT_TRUE(came > 10.0);
    TEST_ASSERT_DOUBLE_WITHIN(cfg.still_um, came, retracted);
    TEST_ASSERT_TRUE(retracted <= came + 1e-9);
    TEST_ASSERT_TRUE(g.follows >= 3u);
    setUp(); /* the servo stops short of every retraction: the target is followed, not the steps */
    follow_after_a_descent(0.6, false, &retracted, &came);
    TEST_ASSERT_DOUBLE_WITHIN(cfg.still_um, came, retracted);
    setUp(); /* a lone neuron: the tip stands */
    follow_after_a_descent(1.0, true, &retracted, &came);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, retracted);
    TEST_ASSERT_EQUAL_UINT32(0u, g.follows);
}

/* Rule 5 with near_scale: the louder the unit that may be ahead, the shorter
 * the advance: move_near_um × amp_slow / amplitude. */
static void test_advances_shorten_as_the_unit_gets_louder(void)
{
    cfg.near_scale = true;
    TEST_ASSERT_EQUAL_INT(MD_OK, ag_init(&g, &cfg));
    ag_output_t out = step1(2.0 * cfg.amp_slow, 0.0, 30.0); /* growth not known yet */
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 0.5 * cfg.move_near_um, out.move_um);
    TEST_ASSERT_EQUAL_INT(AG_SLOWED, out.action);
    setUp();
    out = step1(2.0 * cfg.amp_slow, 0.0, 30.0); /* off: move_near_um */
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, cfg.move_near_um, out.move_um);
}

static void test_invalid_input_holds_and_is_counted(void)
{
    const ag_unit_t bad[2] = {{AG_UNIT_RAW, NAN}, {1u, -1.0}};
    ag_output_t out;
    for (size_t i = 0u; i < 2u; ++i) {
        const ag_input_t in = {&bad[i], 1u, 0.0, next_time(), 20.0, false};
        TEST_ASSERT_EQUAL_INT(MD_E_ARG, ag_apply(&g, &in, &out));
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, 0.0, out.move_um);
        TEST_ASSERT_EQUAL_INT(AG_BAD_INPUT, out.action);
    }
    const ag_unit_t ok = {AG_UNIT_RAW, 10.0};
    const ag_input_t nan_depth = {&ok, 1u, NAN, next_time(), 20.0, false};
    const ag_input_t too_many = {&ok, AG_UNITS_MAX + 1u, 0.0, next_time(), 20.0, false};
    const ag_input_t null_units = {NULL, 1u, 0.0, next_time(), 20.0, false};
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ag_apply(&g, &nan_depth, &out));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ag_apply(&g, &too_many, &out));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ag_apply(&g, &null_units, &out));
    const ag_input_t now = {&ok, 1u, 0.0, next_time(), 20.0, false};
    const ag_input_t earlier = {&ok, 1u, 0.0, now.time_s - 1.0, 20.0, false};
    const ag_input_t nan_time = {&ok, 1u, 0.0, NAN, 20.0, false};
    TEST_ASSERT_EQUAL_INT(MD_OK, ag_apply(&g, &now, &out));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ag_apply(&g, &earlier, &out));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ag_apply(&g, &nan_time, &out));
    TEST_ASSERT_EQUAL_INT(AG_BAD_INPUT, out.action);
    TEST_ASSERT_EQUAL_UINT32(7u, g.bad_inputs);
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ag_apply(NULL, &nan_depth, &out));
    ag_config_t c = cfg;
    c.amp_slow = c.amp_stop;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ag_config_check(&c));
    c = cfg;
    c.growth_stop = c.growth_max * 1.5;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ag_config_check(&c));
    c = cfg;
    c.relax_frac = 1.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ag_config_check(&c));
    c = cfg;
    c.fence_lapse = 0u;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ag_config_check(&c));
    c = cfg;
    c.baseline_new_um = c.baseline_min_um + 1.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ag_config_check(&c));
    c = cfg;
    c.pace_um = -1.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ag_config_check(&c));
    c = cfg;
    c.settle_um = NAN;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ag_config_check(&c));
    c = cfg;
    c.top_k = 0u;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ag_init(&g, &c));
}

static void test_robust_amplitude_is_the_kth_largest_window(void)
{
    static int16_t w[8][4];
    memset(w, 0, sizeof w);
    for (int j = 0; j < 8; ++j) {
        w[j][1] = (int16_t)(-10 * (j + 1)); /* ptp 10 (j + 1) + 5 */
        w[j][2] = 5;
    }
    double a = -1.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, ag_robust_amplitude_i16(&w[0][0], 8u, 4u, 4u, 0.5, 2.5, 3u, &a));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, (60.0 + 5.0) * 0.5 / 2.5, a); /* 3rd largest: j = 5 */
    TEST_ASSERT_EQUAL_INT(MD_OK, ag_robust_amplitude_i16(&w[0][0], 2u, 4u, 4u, 0.5, 2.5, 3u, &a));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 0.0, a); /* fewer windows than k: too little to judge */
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ag_robust_amplitude_i16(&w[0][0], 8u, 4u, 5u, 0.5, 2.5, 3u, &a));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ag_robust_amplitude_i16(&w[0][0], 8u, 4u, 4u, 0.5, 0.0, 3u, &a));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ag_robust_amplitude_i16(NULL, 8u, 4u, 4u, 0.5, 2.5, 3u, &a));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_a_neuron_on_the_path_is_never_reached);
    RUN_TEST(test_a_neuron_passed_at_a_safe_distance_does_not_stop_the_advance);
    RUN_TEST(test_advances_are_shortened_while_a_loud_unit_may_be_ahead);
    RUN_TEST(test_a_new_track_rising_faster_than_any_neuron_beside_the_track_gets_a_ceiling);
    RUN_TEST(test_a_new_track_rising_like_a_neuron_beside_the_track_only_slows);
    RUN_TEST(test_a_loud_unit_beside_the_tip_does_not_slow_the_search);
    RUN_TEST(test_noise_at_a_standstill_never_retracts);
    RUN_TEST(test_a_unit_climbing_at_a_standstill_makes_the_electrode_give_way);
    RUN_TEST(test_a_slow_creep_towards_a_standing_tip_adds_up_to_a_retraction);
    RUN_TEST(test_a_unit_saturating_at_its_ceiling_holds_the_electrode);
    RUN_TEST(test_a_neuron_drifting_onto_a_tip_at_its_ceiling_is_given_way);
    RUN_TEST(test_the_give_back_of_an_advance_retracts_before_it_comes);
    RUN_TEST(test_a_neuron_on_the_path_in_relaxing_tissue_is_never_reached);
    RUN_TEST(test_a_ceiling_set_near_the_soma_gives_way_as_the_tissue_gives_back);
    RUN_TEST(test_the_fence_follows_a_unit_that_moves_away);
    RUN_TEST(test_the_fence_holds_when_a_ceiling_lapses);
    RUN_TEST(test_a_probe_past_the_fence_finds_the_neuron_beside_the_track);
    RUN_TEST(test_a_probe_towards_a_neuron_on_the_path_goes_back);
    RUN_TEST(test_an_artefact_burst_does_not_freeze_the_search);
    RUN_TEST(test_amp_stop_is_a_ceiling_for_every_unit);
    RUN_TEST(test_the_pace_bounds_the_give_back_still_to_come);
    RUN_TEST(test_the_tissue_settles_after_the_give_back);
    RUN_TEST(test_a_standing_tip_follows_the_give_back);
    RUN_TEST(test_advances_shorten_as_the_unit_gets_louder);
    RUN_TEST(test_invalid_input_holds_and_is_counted);
    RUN_TEST(test_robust_amplitude_is_the_kth_largest_window);
    return UNITY_END();
}
