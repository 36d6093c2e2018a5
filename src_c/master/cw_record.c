/* Recording (clockwork/engine/recording.py): a point into the
 * recorder's rows (on the grid, every stride-th, or at events) and its
 * ticks.
 */

#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "cw_master.h"

void record_point(cw_master *m, cw_recorder *r)
{
    if (r->tick_port >= 0) {
        double tt = m->ports[r->tick_port].out[r->tick_pos];
        if (tt != r->last_tick && tt > 0) {
            r->ticks[r->n_ticks++] = tt;
            r->last_tick = tt;
        }
    }
    if (!r->n_cols)
        return;
    double k = (m->t - m->start_time) / m->step;
    if (fabs(k - nearbyint(k)) < 1e-6) {  /* on the grid (events add points off it) */
        r->grid_seen++;
        if (r->grid_seen % r->stride)
            return;
    } else if (r->has_interval) {
        return;
    }
    double *row = &r->rows[(size_t)r->n_rows * (size_t)(r->n_cols + 1)];
    row[0] = m->t;
    for (int c = 0; c < r->n_cols; c++)
        row[c + 1] = m->ports[r->col_port[c]].out[r->col_pos[c]];
    r->n_rows++;
}

/* Record the current point (after a divergence check that found every output legal). */
CW_EXPORT void cw_record_point(cw_master *m, cw_recorder *r)
{
    record_point(m, r);
}
