/* Unity tests (pio test -e native, or on a cell): the golden vectors reproduce the host build's checksums. */
#include <unity.h>
#include "mc_cell.h"
#include "golden_vectors.h"
/* the shared generator, compiled into the test (one implementation, in metacell_tools/fwcheck) */
#include "../../metacell_tools/fwcheck/csrc/mc_vectors.c"

static const mcv_api_t api = MCV_API_DIRECT;
static mcv_sink_t sink;
static uint32_t one_record[MCV_WORDS];
static uint32_t n_run;
static uint32_t sample_hits, sample_bad_index;
static int sample_bad_word = -1;

/* Called with one buffered record: check it against the sample table. */
static void check_record(mcv_sink_t *s)
{
    if (s->n_words) {
        uint32_t idx = s->n_records - 1u;
        for (int k = 0; k < GOLDEN_N_SAMPLES; k++) {
            if (golden_samples[k][0] != idx)
                continue;
            sample_hits++;
            for (int w = 0; w < MCV_WORDS; w++)
                if (golden_samples[k][1 + w] != s->data[w] && sample_bad_word < 0) {
                    sample_bad_word = w;
                    sample_bad_index = idx;
                }
        }
    }
    s->n_words = 0;
}

static void run_once(void)
{
    if (n_run)
        return;
    mcv_sink_init(&sink, one_record, MCV_WORDS);
    sink.flush = check_record;
    n_run = mcv_run(&api, GOLDEN_SEED, &sink);
}

void setUp(void) { run_once(); }
void tearDown(void) {}

static void test_record_count(void)
{
    TEST_ASSERT_EQUAL_UINT32(GOLDEN_N_RECORDS, n_run);
    TEST_ASSERT_TRUE(n_run >= 100000u);
    TEST_ASSERT_EQUAL_UINT32(0, sink.overflow);
}

static void check_family(int fam, const char *name)
{
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(golden_fam_count[fam], sink.fam_count[fam], name);
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(golden_fam_fnv[fam], sink.fam_fnv[fam], name);
}

static void test_reaction_vectors(void) { check_family(MCV_FAM_REACTION, "reaction law"); }
static void test_param_validation_vectors(void) { check_family(MCV_FAM_PARAMS, "parameter validation"); }
static void test_drive_vectors(void) { check_family(MCV_FAM_DRIVE, "drive command"); }
static void test_quadrature_vectors(void) { check_family(MCV_FAM_QUAD, "quadrature decoder"); }
static void test_cell_tick_vectors(void) { check_family(MCV_FAM_CELL, "cell tick sequences"); }

static void test_sample_records(void)
{
    TEST_ASSERT_EQUAL_UINT32(GOLDEN_N_SAMPLES, sample_hits);
    TEST_ASSERT_EQUAL_INT_MESSAGE(-1, sample_bad_word, "a sample record differs (word index)");
}

static void test_overall_checksum(void) { TEST_ASSERT_EQUAL_HEX32(GOLDEN_FNV, sink.fnv); }

static int run_all(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_record_count);
    RUN_TEST(test_reaction_vectors);
    RUN_TEST(test_param_validation_vectors);
    RUN_TEST(test_drive_vectors);
    RUN_TEST(test_quadrature_vectors);
    RUN_TEST(test_cell_tick_vectors);
    RUN_TEST(test_sample_records);
    RUN_TEST(test_overall_checksum);
    return UNITY_END();
}

#ifdef ARDUINO
#include <Arduino.h>
void setup(void)
{
    delay(2000); /* let the USB serial monitor attach */
    run_all();
}
void loop(void) {}
#else
int main(void) { return run_all(); }
#endif
