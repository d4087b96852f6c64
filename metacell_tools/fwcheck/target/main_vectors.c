/* QEMU golden-vector program: runs mc_vectors against the linked library, streams records to a host file. */
#include "semihost.h"
#include "mc_vectors.h"
#include "mc_cell.h"

#ifndef FW_SEED
#define FW_SEED 0x2545F491u
#endif

static const mcv_api_t api = MCV_API_DIRECT;

static uint32_t buf[64 * MCV_WORDS];
static int out_fd = -1;
static int write_failed;

static void flush(mcv_sink_t *s)
{
    if (s->n_words && sh_write(out_fd, s->data, s->n_words * 4u) != 0)
        write_failed = 1;
    s->n_words = 0;
}

int main(void)
{
    mcv_sink_t sink;
    out_fd = sh_open("vectors.bin", 5); /* "wb", relative to QEMU's working dir */
    if (out_fd < 0) {
        sh_puts("fwcheck: cannot open vectors.bin\n");
        return 1;
    }
    mcv_sink_init(&sink, buf, sizeof buf / sizeof buf[0]);
    sink.flush = flush;
    uint32_t n = mcv_run(&api, FW_SEED, &sink);
    /* trailer: magic, record count, checksum */
    uint32_t tail[3] = {0x4d435654u, n, sink.fnv};
    if (sh_write(out_fd, tail, sizeof tail) != 0)
        write_failed = 1;
    if (write_failed || sink.overflow || n != MCV_N_TOTAL) {
        sh_puts("fwcheck: vector run failed\n");
        return 1;
    }
    return 0;
}
