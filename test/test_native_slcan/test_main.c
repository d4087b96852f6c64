/* Unity suite (pio test -e native): the SLCAN line parser and frame encoder against the SLCAN vectors pytest uses. */
#include <string.h>
#include <unity.h>
#include "bus/mc_slcan.h"
#include "bus_vectors_slcan.h" /* generated into the build directory from tests/firmware/vectors/slcan.py */

static mc_slcan_t s;
static mc_can_frame_t frame;
static char reply[MC_SLCAN_REPLY_MAX];

void setUp(void) {}
void tearDown(void) {}

/* Feed the bytes and a CR one at a time; the event of the last byte (reply[] holds its answer). */
static int feed(const uint8_t *bytes, uint32_t n)
{
    int ev = MC_SLCAN_EV_NONE;
    for (uint32_t k = 0; k <= n; k++)
        ev = mc_slcan_rx(&s, k < n ? bytes[k] : (uint8_t)'\r', &frame, reply);
    return ev;
}

static void run_line(const sv_line_t *v)
{
    const char *msg = v->name;
    mc_slcan_init(&s);
    if (v->state)
        TEST_ASSERT_EQUAL_INT_MESSAGE(MC_SLCAN_EV_REPLY, feed((const uint8_t *)(v->state == 2 ? "L" : "O"), 1), msg);
    uint16_t errors = s.errors;
    memset(&frame, 0, sizeof frame);
    int ev = feed(v->line, v->len);
    TEST_ASSERT_EQUAL_INT_MESSAGE(v->kind, ev, msg);
    TEST_ASSERT_EQUAL_STRING_MESSAGE(v->reply, reply, msg);
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(errors + (v->kind == MC_SLCAN_EV_ERROR), s.errors, msg);
    if (v->kind == MC_SLCAN_EV_FRAME) {
        TEST_ASSERT_EQUAL_HEX32_MESSAGE(v->id, frame.id, msg);
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(v->dlc, frame.dlc, msg);
        if (!(v->id & MC_CAN_RTR) && v->dlc)
            TEST_ASSERT_EQUAL_HEX8_ARRAY_MESSAGE(v->data, frame.data, v->dlc, msg);
    }
}

static void run_lines(int kind)
{
    int n = 0;
    for (int k = 0; k < SV_N_LINES; k++)
        if (sv_lines[k].kind == kind) {
            run_line(&sv_lines[k]);
            n++;
        }
    TEST_ASSERT_TRUE_MESSAGE(n > 0, "no vector of this kind");
}

static void test_frame_lines(void) { run_lines(MC_SLCAN_EV_FRAME); }
static void test_command_lines(void) { run_lines(MC_SLCAN_EV_REPLY); }
static void test_malformed_lines_rejected(void) { run_lines(MC_SLCAN_EV_ERROR); }
static void test_empty_lines(void) { run_lines(MC_SLCAN_EV_NONE); }

static void test_encoder(void)
{
    char out[MC_SLCAN_FRAME_MAX + 1];
    for (int k = 0; k < SV_N_ENCODE; k++) {
        const sv_encode_t *v = &sv_encode[k];
        mc_can_frame_t f;
        mc_slcan_init(&s);
        s.timestamps = v->timestamps;
        f.id = v->id;
        f.dlc = v->dlc;
        memcpy(f.data, v->data, 8);
        uint32_t n = mc_slcan_encode(&s, &f, v->ts_ms, out);
        TEST_ASSERT_TRUE_MESSAGE(n <= MC_SLCAN_FRAME_MAX, v->text);
        out[n] = 0;
        TEST_ASSERT_EQUAL_STRING_MESSAGE(v->text, out, v->text);
    }
}

static int run_all(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_frame_lines);
    RUN_TEST(test_command_lines);
    RUN_TEST(test_malformed_lines_rejected);
    RUN_TEST(test_empty_lines);
    RUN_TEST(test_encoder);
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
