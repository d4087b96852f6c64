/* The world's time loop: plant windows, rounds in which the boards run apart in time, and the worker threads. */
#define _POSIX_C_SOURCE 200809L   /* pthreads, sched_yield */
#include <stdio.h>
#include <string.h>
#include <pthread.h>
#include <sched.h>
#include "sam_world.h"

/*
 * Time loop (sam_world_run). The plant advances in windows of W: at the start of each window it steps over it
 * with each motor's mean voltage and awake fraction of the window before (a lag of one window) and turns the
 * encoders' count changes into pin edges at the times linear interpolation of the angle gives, inside the window.
 *
 * The boards then run the window apart in time, each as far as nothing another board does can still reach it
 * (conservative parallel simulation). Boards affect each other only through bus steps that take effect at least
 * T_MIN (the shortest SCL period, link_i2c_bus.c) after their cause, and a board that sends a step stops T_MIN after
 * the step takes effect (the receiver may answer then). The primary runs as far as the cells let it (a cell that
 * holds SCL may answer any time from T_MIN on; one with a step to take may answer it); each cell that may answer
 * then runs as far as the primary lets it: T_MIN past the primary, or to the window's end while the primary sees SCL
 * held and has no release to take; the others run once the primary lets them reach the round's end. So no step
 * ever reaches a board that has run past it (checked), and results do not depend on how far boards run at a time
 * (round_s), nor on fast-forwarding, nor on the order cells run in.
 * World-level faults start and end at round boundaries placed at their times.
 */

static int run_board(sam_world_t *w, sam_mcu_t *m, uint64_t to, int *moved)
{
    if (m->pos >= to)
        return 0;
    *moved = 1;
    if (sam_mcu_run(m, to))
        return sam_world_fail(w, "%s", m->errmsg);
    return 0;
}

/* ---------------------------------------------------------------- workers: cells that cannot affect anyone in a
 * phase run at the same time on several threads (each on its own Unicorn; what they touch is their own) */

#define SPIN_PAUSES 300    /* a worker waits this long for the next jobs before it sleeps */
#define SPIN_YIELDS 0
#define PARALLEL_MIN 4     /* fewer jobs run on the calling thread: waking workers costs more */

static void relax(void)
{
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
}

static void do_jobs(sam_world_t *w)
{
    sam_pool_t *pl = &w->pool;
    for (;;) {
        int i = __atomic_fetch_add(&pl->next, 1, __ATOMIC_ACQ_REL);
        if (i >= pl->njobs)
            return;
        sam_mcu_run(pl->job[i], pl->job_to[i]);
    }
}

static void *worker_main(void *arg)
{
    sam_world_t *w = arg;
    sam_pool_t *pl = &w->pool;
    unsigned seen = 0;
    for (;;) {
        int spins = 0;
        while (__atomic_load_n(&pl->gen, __ATOMIC_ACQUIRE) == seen && !__atomic_load_n(&pl->quit, __ATOMIC_ACQUIRE)) {
            if (++spins < SPIN_PAUSES) {
                relax();
            } else if (spins < SPIN_PAUSES + SPIN_YIELDS) {
                sched_yield();
            } else {
                pthread_mutex_lock(&pl->mu);
                pl->sleeping++;
                while (__atomic_load_n(&pl->gen, __ATOMIC_ACQUIRE) == seen && !pl->quit)
                    pthread_cond_wait(&pl->cv, &pl->mu);
                pl->sleeping--;
                pthread_mutex_unlock(&pl->mu);
                spins = 0;
            }
        }
        if (__atomic_load_n(&pl->quit, __ATOMIC_ACQUIRE))
            return NULL;
        seen = __atomic_load_n(&pl->gen, __ATOMIC_ACQUIRE);
        do_jobs(w);
        __atomic_fetch_sub(&pl->busy, 1, __ATOMIC_ACQ_REL);
    }
}

int sam_world_pool_start(sam_world_t *w, int nthreads)
{
    sam_pool_t *pl = &w->pool;
    pl->nworkers = 0;
    if (nthreads <= 1)
        return 0;
    if (pthread_mutex_init(&pl->mu, NULL) || pthread_cond_init(&pl->cv, NULL))
        return sam_world_fail(w, "threads: cannot create a mutex");
    pl->init = 1;
    for (int k = 0; k < nthreads - 1 && k < SAM_MAX_THREADS - 1; k++) {
        if (pthread_create(&pl->th[k], NULL, worker_main, w))
            return sam_world_fail(w, "threads: cannot start worker %d of %d", k + 1, nthreads - 1);
        pl->nworkers++;
    }
    return 0;
}

void sam_world_pool_stop(sam_world_t *w)
{
    sam_pool_t *pl = &w->pool;
    if (!pl->init)
        return;
    pthread_mutex_lock(&pl->mu);
    __atomic_store_n(&pl->quit, 1, __ATOMIC_RELEASE);
    pthread_cond_broadcast(&pl->cv);
    pthread_mutex_unlock(&pl->mu);
    for (int k = 0; k < pl->nworkers; k++)
        pthread_join(pl->th[k], NULL);
    pthread_cond_destroy(&pl->cv);
    pthread_mutex_destroy(&pl->mu);
    pl->init = 0;
}

/* Run the jobs (boards that cannot affect each other or anyone else until their target): on the workers and
 * this thread when there are workers and more than one job. */
static int run_jobs(sam_world_t *w)
{
    sam_pool_t *pl = &w->pool;
    if (pl->njobs == 0)
        return 0;
    pl->next = 0;
    if (pl->nworkers == 0 || pl->njobs < PARALLEL_MIN) {
        do_jobs(w);
    } else {
        __atomic_store_n(&pl->busy, pl->nworkers, __ATOMIC_RELEASE);
        pthread_mutex_lock(&pl->mu);   /* a worker checks gen and goes to sleep under this lock: no lost wake-up */
        __atomic_fetch_add(&pl->gen, 1, __ATOMIC_ACQ_REL);
        if (pl->sleeping)
            pthread_cond_broadcast(&pl->cv);
        pthread_mutex_unlock(&pl->mu);
        do_jobs(w);
        for (int spins = 0; __atomic_load_n(&pl->busy, __ATOMIC_ACQUIRE) > 0; spins++) {
            if (spins < SPIN_PAUSES)
                relax();
            else
                sched_yield();
        }
    }
    for (int k = 0; k < pl->njobs; k++)   /* in board order: the same error whatever ran first */
        if (pl->job[k]->err)
            return sam_world_fail(w, "%s", pl->job[k]->errmsg);
    return 0;
}

/* Every board from w->t to `target`, each as far as the others let it at a time (see the top of this file). */
static int round_to(sam_world_t *w, uint64_t target)
{
    sam_mcu_t *p = w->primary_mcu >= 0 ? w->mcu[w->primary_mcu] : NULL;
    sam_pool_t *pl = &w->pool;
    for (;;) {
        int moved = 0, behind = 0;
        if (p) {
            uint64_t h = target;
            for (int i = 0; i < w->nmcu; i++)
                if (w->mcu[i] && w->mcu[i] != p) {
                    uint64_t e = sam_bus_eot_slave(w->mcu[i]);
                    h = e < h ? e : h;
                }
            if (run_board(w, p, h, &moved))
                return -1;
        }
        /* first, one at a time, the cells that may answer the primary (what they send may let the others run
         * further); then the others, which cannot send anything before their target, together, and only once the
         * primary lets them reach the target: while it and a cell it addressed answer each other in steps of T_MIN,
         * the rest wait (nothing they could do bounds the primary, and a board that is behind takes what reaches it
         * in time order when it runs), so that they run the round in one go rather than in a step per answer */
        for (int i = 0; i < w->nmcu; i++) {
            sam_mcu_t *m = w->mcu[i];
            if (!m || m == p || sam_bus_eot_slave(m) == SAM_NEVER)
                continue;
            uint64_t h = p ? sam_bus_eot_master(p) : SAM_NEVER;
            if (run_board(w, m, h < target ? h : target, &moved))
                return -1;
        }
        uint64_t h = p ? sam_bus_eot_master(p) : SAM_NEVER;
        h = h < target ? h : target;
        pl->njobs = 0;
        for (int i = 0; h >= target && i < w->nmcu; i++) {   /* (h < target: they wait, see above) */
            sam_mcu_t *m = w->mcu[i];
            if (!m || m == p || m->pos >= h || sam_bus_eot_slave(m) != SAM_NEVER)
                continue;
            moved = 1;
            if (sam_mcu_idle_to(m, h))
                continue;   /* parked through h: nothing to run */
            pl->job[pl->njobs] = m;
            pl->job_to[pl->njobs++] = h;
        }
        if (run_jobs(w))
            return -1;
        for (int i = 0; i < w->nmcu; i++)
            if (w->mcu[i] && w->mcu[i]->pos < target)
                behind = 1;
        if (!behind)
            return 0;
        if (!moved)
            return sam_world_fail(w, "the boards wait for each other at t = %.6f s (scheduling error)",
                        (double)w->t / (double)SAM_TU_HZ);
    }
}

int sam_world_run(sam_world_t *w, uint64_t t_end)
{
    if (w->err[0])
        return -1;
    while (w->t < t_end) {
        if (w->t >= w->next_window) {
            if (sam_world_window(w, w->next_window))
                return -1;
            w->next_window += w->window_tu;
        }
        sam_world_faults_apply(w);
        uint64_t target = t_end < w->next_window ? t_end : w->next_window;
        uint64_t f = sam_world_next_fault(w);
        if (f > w->t && f < target)
            target = f;
        if (w->t + w->round_tu < target)
            target = w->t + w->round_tu;
        int rc = round_to(w, target);
        sam_world_collect_notes(w);
        if (rc)
            return -1;
        w->t = target;
    }
    return 0;
}
