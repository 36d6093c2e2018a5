/* FMI 3.0 clocks in the compiled core: the twin of ClockedMaster.step
 * (clockwork/engine/clocks.py). Its struct (cw_clocks) is in cw_structs.h.
 *
 * The core keeps the next tick of every input clock the master ticks
 * (Python writes them after each event): a step that would pass one is
 * cut to land on it, and a step that ends at a tick, at an event an FMU
 * signalled inside it, or at a located state event where FMUs have output
 * clocks, returns CW_CLOCK_EVENT. Python then runs the event (the FMI calls
 * of Event Mode or Scheduled Execution, the records) with the Python
 * engine's own code and calls again, so both engines make the same calls
 * with the same values. A scene without clocks has no cw_clocks (NULL).
 */

#include <math.h>

#include "cw_master.h"

/* The step from t cut to land on the earliest tick after t (not at t). */
double clocks_cut(const cw_clocks *c, double t, double h)
{
    double tick = INFINITY;
    for (int i = 0; i < c->n_next; i++) {
        double x = c->next[i];
        if (x > t && !cw_isclose(x, t) && x < tick)
            tick = x;
    }
    if (t + h > tick && !cw_isclose(t + h, tick))
        h = tick - t;
    return h;
}

/* Whether the step that ended at t ended at an event of the clocks. */
int clocks_due(const cw_clocks *c, double t, int after_event_step)
{
    if (c->pending || (c->asked && after_event_step))
        return 1;
    for (int i = 0; i < c->n_next; i++)
        if (c->next[i] <= t || cw_isclose(c->next[i], t))
            return 1;
    return 0;
}

/* The step of an instance that has no step of its own (FMI 3.0 Scheduled
 * Execution: its partitions run when Python activates their clocks). */
CW_EXPORT int cw_wait_step(void *comp, double t, double h, int no_set_prior)
{
    (void)comp; (void)t; (void)h; (void)no_set_prior;
    return FMI_OK;
}
