/* Unity suite (pio test -e native): the cell's I2C register handler against the register vectors pytest uses. */
#include <string.h>
#include <unity.h>
#include "mc_cell.h"
#include "bus/mc_regs.h"
#include "bus/mc_crc8.h"
#include "bus_vectors_regs.h" /* generated into the build directory from tests/firmware/vectors/regs.py */

static mc_cell_t cell;
static mc_regs_t regs;
static mc_quad_snap_t qa, qb;
static uint8_t buf[64];

void setUp(void) {}
void tearDown(void) {}

/* A fresh cell with one tick behind it (the state every vector starts from). */
static void fresh(void)
{
    mc_cell_init(&cell);
    TEST_ASSERT_EQUAL_INT(MC_OK, mc_regs_init(&regs, &cell, RV_ADDR, RV_BUILD, NULL));
    memset(&qa, 0, sizeof qa);
    memset(&qb, 0, sizeof qb);
    mc_regs_tick(&regs, &cell, &qa, &qb);
}

/* Everything a write may change (the tick-evolving state excluded), as bytes. */
static uint32_t config(uint8_t *out)
{
    uint32_t n = 0;
#define ADD(field)                                      \
    do {                                                \
        memcpy(out + n, &(field), sizeof(field));       \
        n += (uint32_t)sizeof(field);                   \
    } while (0)
    ADD(cell.law);
    ADD(cell.drive);
    ADD(cell.zero);
    ADD(cell.enabled);
    ADD(cell.bemf_comp);
    ADD(cell.pert_torque);
    ADD(cell.pert_ticks);
    ADD(cell.pert_chain);
    ADD(cell.faults);
    ADD(regs.params[regs.params_idx]);
#undef ADD
    return n;
}

static int32_t le32(const uint8_t *p)
{
    return (int32_t)((uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24);
}

static uint32_t read_block(void) { return mc_regs_on_request(&regs, buf, sizeof buf); }

/* Run one vector: write, tick, then check read pointer, snapshot, PARAMS block and (if rejected) the config. */
static void run_case(const rv_case_t *v)
{
    static uint8_t before[512], after[512];
    const char *msg = v->name;
    fresh();
    uint32_t nb = config(before);
    mc_regs_on_receive(&regs, v->frame, v->len);
    mc_regs_tick(&regs, &cell, &qa, &qb);
    if (v->pointer) {
        TEST_ASSERT_TRUE_MESSAGE(read_block() > 0, msg);
        TEST_ASSERT_EQUAL_HEX8_MESSAGE(v->read_tag, buf[0], msg);
    }
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(MC_BLK_SNAPSHOT_LEN, read_block(), msg);
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(MC_BLK_SNAPSHOT_TAG, buf[MC_SNAPSHOT_TAG], msg);
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(v->result, buf[MC_SNAPSHOT_CMD_RESULT], msg);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(v->rejected, buf[MC_SNAPSHOT_REJECTED], msg);
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(v->bus_err, buf[MC_SNAPSHOT_BUS_ERR] | buf[MC_SNAPSHOT_BUS_ERR + 1] << 8, msg);
    if (v->result == MC_RES_OK)
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(v->seq, buf[MC_SNAPSHOT_CMD_SEQ], msg);
    if (v->result != MC_RES_OK) {
        TEST_ASSERT_EQUAL_UINT32_MESSAGE(nb, config(after), msg);
        TEST_ASSERT_EQUAL_MEMORY_MESSAGE(before, after, nb, msg);
    }
    /* the parameters in force, read back through the PARAMS block */
    uint8_t ptr[4] = {MC_REG_POINTER, 0, MC_BLK_PARAMS, 0};
    uint8_t hdr = (uint8_t)(RV_ADDR << 1);
    ptr[3] = mc_crc8_update(mc_crc8(&hdr, 1), ptr, 3);
    mc_regs_on_receive(&regs, ptr, 4);
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(MC_BLK_PARAMS_LEN, read_block(), msg);
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(MC_BLK_PARAMS_TAG, buf[MC_PARAMS_TAG], msg);
    static const uint8_t off[5] = {MC_PARAMS_K_AB, MC_PARAMS_SIGMA, MC_PARAMS_K1, MC_PARAMS_K2, MC_PARAMS_ASTAR};
    for (int k = 0; k < 5; k++)
        TEST_ASSERT_EQUAL_INT32_MESSAGE(v->params[k], le32(buf + off[k]), msg);
}

/* The vectors in three groups, so a failure names its kind. */
static void run_group(int (*pick)(const rv_case_t *))
{
    int n = 0;
    for (int k = 0; k < RV_N; k++)
        if (pick(&rv_cases[k])) {
            run_case(&rv_cases[k]);
            n++;
        }
    TEST_ASSERT_TRUE_MESSAGE(n > 0, "no vector in this group");
}

static int is_accepted(const rv_case_t *v) { return !v->pointer && v->result == MC_RES_OK; }
static int is_rejected(const rv_case_t *v) { return !v->pointer && v->result != MC_RES_OK; }
static int is_pointer(const rv_case_t *v) { return v->pointer; }

static void test_accepted_writes(void) { run_group(is_accepted); }
static void test_rejected_writes_change_nothing(void) { run_group(is_rejected); }
static void test_pointer_writes(void) { run_group(is_pointer); }

static void test_ident_block(void)
{
    uint8_t ptr[4] = {MC_REG_POINTER, 0, MC_BLK_IDENT, 0};
    uint8_t hdr = (uint8_t)(RV_ADDR << 1);
    fresh();
    ptr[3] = mc_crc8_update(mc_crc8(&hdr, 1), ptr, 3);
    mc_regs_on_receive(&regs, ptr, 4);
    TEST_ASSERT_EQUAL_UINT32(MC_BLK_IDENT_LEN, read_block());
    TEST_ASSERT_EQUAL_HEX8(MC_BLK_IDENT_TAG, buf[MC_IDENT_TAG]);
    TEST_ASSERT_EQUAL_HEX8(RV_ADDR, buf[MC_IDENT_ADDR]);
    TEST_ASSERT_EQUAL_HEX32(RV_BUILD, (uint32_t)le32(buf + MC_IDENT_BUILD));
}

static int run_all(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_accepted_writes);
    RUN_TEST(test_rejected_writes_change_nothing);
    RUN_TEST(test_pointer_writes);
    RUN_TEST(test_ident_block);
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
