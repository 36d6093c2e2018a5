/* The master core's thread pool (master.threads): workers that sleep on a
 * condition variable between jobs. A job is n items, handed out in small
 * blocks by an atomic counter, so that a slow FMU does not hold up the
 * others' threads; the calling thread takes items too. Every item runs on
 * exactly one thread. Once every item is taken the job is closed: a worker
 * that wakes later (a busy machine) stays out of it, and the caller waits
 * only for the workers inside, so that nothing of a job outlives
 * cw_pool_run and no job waits for a thread the system has not run yet. */

#include "cw_pool.h"

#include <pthread.h>
#include <stdlib.h>
#include <unistd.h>

#define CW_EXPORT __attribute__((visibility("default")))

struct cw_pool {
    int n_workers;
    pid_t owner;            /* the process that made the threads (a forked child has none of them) */
    pthread_t *workers;
    pthread_mutex_t lock;
    pthread_cond_t start;   /* a new job, or stop */
    pthread_cond_t done;    /* the last worker left the job */
    unsigned long job;      /* counts the jobs handed out */
    int stopping;
    int open;               /* the current job takes workers */
    int inside;             /* workers in the current job */
    /* the current job */
    cw_pool_fn fn;
    void *ctx;
    int n_items;
    int next;               /* the next item to take (atomic) */
};

static void take_items(cw_pool *pool)
{
    /* Items in blocks of a quarter of an even share: few trips to the
     * shared counter when items are short (an FMU step can take 50 ns),
     * and still some balance when they are not. */
    int block = pool->n_items / (4 * (pool->n_workers + 1));
    if (block < 1)
        block = 1;
    for (;;) {
        int first = __atomic_fetch_add(&pool->next, block, __ATOMIC_RELAXED);
        if (first >= pool->n_items)
            return;
        int end = first + block < pool->n_items ? first + block : pool->n_items;
        for (int item = first; item < end; item++)
            pool->fn(pool->ctx, item);
    }
}

static void *worker(void *arg)
{
    cw_pool *pool = arg;
    unsigned long seen = 0;
    for (;;) {
        pthread_mutex_lock(&pool->lock);
        while (pool->job == seen && !pool->stopping)
            pthread_cond_wait(&pool->start, &pool->lock);
        if (pool->stopping) {
            pthread_mutex_unlock(&pool->lock);
            return NULL;
        }
        seen = pool->job;
        if (pool->open) {
            pool->inside++;
            pthread_mutex_unlock(&pool->lock);
            take_items(pool);
            pthread_mutex_lock(&pool->lock);
            if (--pool->inside == 0)
                pthread_cond_signal(&pool->done);
        }
        pthread_mutex_unlock(&pool->lock);
    }
}

CW_EXPORT cw_pool *cw_pool_new(int threads)
{
    if (threads < 2)
        return NULL;
    cw_pool *pool = calloc(1, sizeof *pool);
    if (!pool)
        return NULL;
    pool->workers = calloc((size_t)threads - 1, sizeof *pool->workers);
    if (!pool->workers) {
        free(pool);
        return NULL;
    }
    pool->owner = getpid();
    pthread_mutex_init(&pool->lock, NULL);
    pthread_cond_init(&pool->start, NULL);
    pthread_cond_init(&pool->done, NULL);
    for (int k = 0; k < threads - 1; k++) {
        if (pthread_create(&pool->workers[k], NULL, worker, pool) != 0) {
            cw_pool_free(pool);  /* stops the workers made so far */
            return NULL;
        }
        pool->n_workers++;
    }
    return pool;
}

CW_EXPORT void cw_pool_free(cw_pool *pool)
{
    if (!pool || pool->owner != getpid())
        return;  /* a forked child: the threads are the parent's, and so is the memory's fate */
    pthread_mutex_lock(&pool->lock);
    pool->stopping = 1;
    pthread_cond_broadcast(&pool->start);
    pthread_mutex_unlock(&pool->lock);
    for (int k = 0; k < pool->n_workers; k++)
        pthread_join(pool->workers[k], NULL);
    pthread_cond_destroy(&pool->done);
    pthread_cond_destroy(&pool->start);
    pthread_mutex_destroy(&pool->lock);
    free(pool->workers);
    free(pool);
}

void cw_pool_run(cw_pool *pool, int n_items, cw_pool_fn fn, void *ctx)
{
    pthread_mutex_lock(&pool->lock);
    pool->fn = fn;
    pool->ctx = ctx;
    pool->n_items = n_items;
    pool->next = 0;
    pool->open = 1;
    pool->job++;
    pthread_cond_broadcast(&pool->start);
    pthread_mutex_unlock(&pool->lock);
    take_items(pool);
    pthread_mutex_lock(&pool->lock);
    pool->open = 0;
    while (pool->inside > 0)
        pthread_cond_wait(&pool->done, &pool->lock);
    pthread_mutex_unlock(&pool->lock);
}
