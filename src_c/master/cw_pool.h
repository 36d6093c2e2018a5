/* A small pool of threads for the master's core: it runs the items of one
 * job at once, each item on exactly one thread (the caller's included),
 * and returns when all are done. See cw_pool.c. */
#ifndef CW_POOL_H
#define CW_POOL_H

typedef struct cw_pool cw_pool;
typedef void (*cw_pool_fn)(void *ctx, int item);

/* A pool of `threads` threads in all: threads - 1 workers and the caller.
 * NULL where threads < 2 or the system refuses a thread. */
cw_pool *cw_pool_new(int threads);
void cw_pool_free(cw_pool *pool);

/* fn(ctx, item) for item = 0 .. n_items - 1, spread over the threads;
 * returns when every call has returned. */
void cw_pool_run(cw_pool *pool, int n_items, cw_pool_fn fn, void *ctx);

#endif
