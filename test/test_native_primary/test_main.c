/* Unity suite (pio test -e native): the primary's poll scheduler and command path against the vectors pytest uses. */
#include <string.h>
#include <unity.h>
#include "bus/mc_primary.h"
#include "bus/mc_crc8.h"
#include "bus_vectors_primary.h" /* generated into the build directory from tests/firmware/vectors/primary.py */

static mc_primary_t p;
static mc_txn_t t;
static uint32_t now;

void setUp(void) {}
void tearDown(void) {}

static void fresh(void)
{
    now = 0;
    mc_primary_init(&p, 0);
}

/* Time advances 10 us while there is nothing to start (the harness rule of the vectors). */
static void start_next(void)
{
    for (uint32_t guard = 0; !mc_primary_next(&p, now, &t); guard++) {
        TEST_ASSERT_TRUE_MESSAGE(guard < 100000u, "the scheduler starts nothing");
        now += 10;
    }
}

static void finish(uint32_t duration, int status, const uint8_t *rx, uint32_t len)
{
    now += duration;
    mc_primary_complete(&p, now, status, rx, len);
}

/* An intact snapshot of cell index i reporting cmd_seq / cmd_result. */
static void snapshot(uint8_t *b, uint32_t i, uint8_t cmd_seq, uint8_t result)
{
    memset(b, 0, MC_BLK_SNAPSHOT_LEN);
    b[MC_SNAPSHOT_TAG] = MC_BLK_SNAPSHOT_TAG;
    b[MC_SNAPSHOT_ADDR] = (uint8_t)(MC_ADDR_BASE + i);
    b[MC_SNAPSHOT_TICK] = 1;
    b[MC_SNAPSHOT_CMD_SEQ] = cmd_seq;
    b[MC_SNAPSHOT_CMD_RESULT] = result;
    b[MC_SNAPSHOT_CRC] = mc_crc8(b, MC_BLK_SNAPSHOT_LEN - 1);
}

static void test_one_poll_cycle(void)
{
    for (int c = 0; c < PV_N_POLL; c++) {
        const pv_poll_t *v = &pv_poll[c];
        const char *msg = v->name;
        fresh();
        for (uint32_t i = 0; i < MC_N_CELLS; i++) {
            const pv_cell_t *x = &v->cell[i];
            start_next();
            TEST_ASSERT_EQUAL_UINT8_MESSAGE(MC_TXN_READ, t.kind, msg);
            TEST_ASSERT_EQUAL_UINT8_MESSAGE(i, t.cell, msg);
            TEST_ASSERT_EQUAL_HEX8_MESSAGE(MC_ADDR_BASE + i, t.addr, msg);
            TEST_ASSERT_EQUAL_UINT8_MESSAGE(MC_BLK_SNAPSHOT_LEN, t.len, msg);
            finish(x->duration, x->status, x->rx, x->len);
        }
        mc_can_frame_t f;
        uint32_t next = 0;
        while (mc_primary_pop(&p, &f)) {
            if (f.id <= MC_CAN_CELL_SAMPLE || f.id > MC_CAN_CELL_SAMPLE + MC_N_CELLS)
                continue;
            while (next < MC_N_CELLS && !v->cell[next].sample)
                next++;
            TEST_ASSERT_TRUE_MESSAGE(next < MC_N_CELLS, msg); /* a sample no vector expects */
            const pv_cell_t *x = &v->cell[next];
            TEST_ASSERT_EQUAL_HEX32_MESSAGE(MC_CAN_CELL_SAMPLE + next + 1, f.id, msg);
            TEST_ASSERT_EQUAL_UINT8_MESSAGE(1, f.data[MC_CAN_CELL_SAMPLE_SEQ], msg);
            TEST_ASSERT_EQUAL_INT16_MESSAGE(x->alpha, (int16_t)(f.data[MC_CAN_CELL_SAMPLE_ALPHA] |
                                                                f.data[MC_CAN_CELL_SAMPLE_ALPHA + 1] << 8), msg);
            TEST_ASSERT_EQUAL_INT16_MESSAGE(x->beta, (int16_t)(f.data[MC_CAN_CELL_SAMPLE_BETA] |
                                                               f.data[MC_CAN_CELL_SAMPLE_BETA + 1] << 8), msg);
            TEST_ASSERT_EQUAL_HEX8_MESSAGE(x->flags, f.data[MC_CAN_CELL_SAMPLE_FLAGS], msg);
            next++;
        }
        while (next < MC_N_CELLS && !v->cell[next].sample)
            next++;
        TEST_ASSERT_EQUAL_UINT32_MESSAGE(MC_N_CELLS, next, msg); /* every expected sample came */
        for (uint32_t i = 0; i < MC_N_CELLS; i++) {
            TEST_ASSERT_EQUAL_UINT16_MESSAGE(v->cell[i].nack, p.cell[i].nack, msg);
            TEST_ASSERT_EQUAL_UINT16_MESSAGE(v->cell[i].integrity, p.cell[i].integrity, msg);
            TEST_ASSERT_EQUAL_UINT16_MESSAGE(v->cell[i].timeout, p.cell[i].timeout, msg);
        }
    }
}

static void test_timeouts_back_off(void)
{
    for (int c = 0; c < PV_N_BACKOFF; c++) {
        const pv_backoff_t *v = &pv_backoff[c];
        const char *msg = v->name;
        uint16_t polls[sizeof v->polls / sizeof v->polls[0]];
        uint32_t n = 0;
        uint8_t b[MC_BLK_SNAPSHOT_LEN];
        fresh();
        while (n < v->n_polls) {
            start_next();
            snapshot(b, t.cell, 0, 0);
            if (t.cell + 1u != v->cell) {
                finish(PV_DURATION_US, MC_I2C_OK, b, sizeof b);
                continue;
            }
            polls[n++] = (uint16_t)p.cycles;
            if (n > v->n_timeouts)
                finish(PV_DURATION_US, MC_I2C_OK, b, sizeof b);
            else if (v->late)
                finish(p.txn_timeout_us + 1u, MC_I2C_OK, b, sizeof b);
            else
                finish(PV_DURATION_US, MC_I2C_TIMEOUT, NULL, 0);
        }
        TEST_ASSERT_EQUAL_UINT16_ARRAY_MESSAGE(v->polls, polls, v->n_polls, msg);
        TEST_ASSERT_EQUAL_UINT16_MESSAGE(v->n_timeouts, p.cell[v->cell - 1].timeout, msg);
        TEST_ASSERT_EQUAL_UINT16_MESSAGE(v->skipped, p.cell[v->cell - 1].skipped, msg);
        for (uint32_t i = 0; i < MC_N_CELLS; i++)
            if (i + 1u != v->cell)
                TEST_ASSERT_EQUAL_UINT16_MESSAGE(0, p.cell[i].timeout + p.cell[i].skipped, msg);
    }
}

static int reported(uint32_t id)
{
    return id == MC_CAN_PRIMARY_REJECT || (id > MC_CAN_CMD_RESULT && id <= MC_CAN_CMD_RESULT + MC_N_CELLS) ||
           (id > MC_CAN_BLOCK_DATA && id <= MC_CAN_BLOCK_DATA + MC_N_CELLS);
}

static void run_command(const pv_cmd_t *v)
{
    const char *msg = v->name;
    uint8_t seq[MC_N_CELLS] = {0}, result[MC_N_CELLS] = {0}, pointer[MC_N_CELLS] = {0};
    uint8_t b[MC_BLK_SNAPSHOT_LEN];
    mc_can_frame_t f;
    fresh();
    for (uint32_t i = 0; i < MC_N_CELLS; i++) { /* one clean cycle: every cell seen */
        start_next();
        snapshot(b, t.cell, 0, 0);
        finish(PV_DURATION_US, MC_I2C_OK, b, sizeof b);
    }
    while (mc_primary_pop(&p, &f))
        ;
    for (uint32_t k = 0; k < v->n_can; k++) {
        f.id = v->can[k].id;
        f.dlc = v->can[k].dlc;
        memcpy(f.data, v->can[k].data, 8);
        mc_primary_can_rx(&p, now, &f);
    }
    uint32_t n = 0;
    for (int step = 0; step < PV_CMD_STEPS; step++) {
        start_next();
        uint32_t i = t.cell;
        int extra = t.kind == MC_TXN_WRITE || pointer[i];
        if (extra) { /* a transaction beyond the polls: the next one the vector lists */
            TEST_ASSERT_TRUE_MESSAGE(n < v->n_txns, msg);
            const pv_txn_t *x = &v->txns[n++];
            TEST_ASSERT_EQUAL_UINT8_MESSAGE(x->kind, t.kind, msg);
            TEST_ASSERT_EQUAL_UINT8_MESSAGE(x->cell, i + 1u, msg);
            TEST_ASSERT_EQUAL_UINT8_MESSAGE(x->len, t.len, msg);
            if (t.kind == MC_TXN_WRITE)
                TEST_ASSERT_EQUAL_HEX8_ARRAY_MESSAGE(x->buf, t.buf, t.len, msg);
        }
        if (t.kind == MC_TXN_WRITE) {
            finish(PV_DURATION_US, v->write_status, NULL, 0);
            if (v->write_status == MC_I2C_OK && t.buf[0] == MC_REG_POINTER) {
                pointer[i] = 1;
            } else if (v->write_status == MC_I2C_OK) {
                seq[i] = t.buf[1];
                result[i] = v->cell_result;
            }
        } else if (pointer[i]) {
            pointer[i] = 0;
            finish(PV_DURATION_US, MC_I2C_OK, v->block_rx, v->block_len);
        } else {
            snapshot(b, i, seq[i], result[i]);
            finish(PV_DURATION_US, MC_I2C_OK, b, sizeof b);
        }
    }
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(v->n_txns, n, msg);
    n = 0;
    while (mc_primary_pop(&p, &f)) {
        if (!reported(f.id))
            continue;
        TEST_ASSERT_TRUE_MESSAGE(n < v->n_frames, msg); /* a frame no vector expects */
        const pv_frame_t *x = &v->frames[n++];
        TEST_ASSERT_EQUAL_HEX32_MESSAGE(x->id, f.id, msg);
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(x->dlc, f.dlc, msg);
        TEST_ASSERT_EQUAL_HEX8_ARRAY_MESSAGE(x->data, f.data, x->dlc, msg);
    }
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(v->n_frames, n, msg);
}

static void test_commands(void)
{
    for (int c = 0; c < PV_N_CMD; c++)
        run_command(&pv_cmd[c]);
}

/* A sheet's primary (mc_primary_set_cells): cells 1..n in order at 0x10.., every sample out, a command beyond n
 * answered NO_CELL in a PRIMARY_REJECT; counts outside 1..MC_MAX_CELLS refused (the same as tests/firmware). */
static void test_a_sheet_of_n_cells(void)
{
    static const uint32_t counts[] = {4, 32, MC_MAX_CELLS};
    uint8_t b[MC_BLK_SNAPSHOT_LEN];
    mc_can_frame_t f;
    for (uint32_t k = 0; k < sizeof(counts) / sizeof(counts[0]); k++) {
        uint32_t n = counts[k], samples = 0;
        fresh();
        TEST_ASSERT_EQUAL_UINT8(MC_N_CELLS, p.n_cells);
        TEST_ASSERT_EQUAL_INT(-1, mc_primary_set_cells(&p, 0));
        TEST_ASSERT_EQUAL_INT(-1, mc_primary_set_cells(&p, MC_MAX_CELLS + 1));
        TEST_ASSERT_EQUAL_INT(0, mc_primary_set_cells(&p, n));
        for (uint32_t i = 0; i < n; i++) {
            start_next();
            TEST_ASSERT_EQUAL_UINT8(i, t.cell);
            TEST_ASSERT_EQUAL_HEX8(MC_ADDR_BASE + i, t.addr);
            snapshot(b, i, 0, 0);
            finish(500, MC_I2C_OK, b, MC_BLK_SNAPSHOT_LEN);
            while (mc_primary_pop(&p, &f))
                if (f.id == MC_CAN_CELL_SAMPLE + i + 1)
                    samples++;
        }
        TEST_ASSERT_EQUAL_UINT32(n, samples);
        start_next();
        TEST_ASSERT_EQUAL_HEX8(MC_ADDR_BASE, t.addr); /* the next cycle starts at cell 1 again */
        TEST_ASSERT_EQUAL_INT(-1, mc_primary_set_cells(&p, 16)); /* not once polling has started */
        while (mc_primary_pop(&p, &f)) {
        }
        memset(&f, 0, sizeof(f));
        f.id = MC_CAN_CMD + n + 1;
        f.dlc = 3;
        f.data[0] = MC_REG_ENABLE;
        f.data[1] = 7;
        f.data[2] = 1;
        mc_primary_can_rx(&p, now, &f);
        TEST_ASSERT_TRUE(mc_primary_pop(&p, &f));
        TEST_ASSERT_EQUAL_HEX32(MC_CAN_PRIMARY_REJECT, f.id);
        TEST_ASSERT_EQUAL_HEX8(MC_RES_NO_CELL, f.data[MC_CAN_PRIMARY_REJECT_REASON]);
    }
}

static int run_all(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_one_poll_cycle);
    RUN_TEST(test_timeouts_back_off);
    RUN_TEST(test_commands);
    RUN_TEST(test_a_sheet_of_n_cells);
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
