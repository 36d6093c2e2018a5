/* The field tables of every struct Python mirrors (cw_structs.h), which
 * the Python side checks its ctypes mirrors against field by field
 * (cw_layout.h, clockwork/fmi/layout.py): cw_layout for the master's and
 * the adapters' structs, cwme_layout for the Model Exchange wrapper's.
 */

#include <string.h>

#include "cw_master.h"
#include "cw_layout.h"

static const cw_field port_layout[] = {
    CW_FIELD(cw_port, comp), CW_FIELD(cw_port, doStep), CW_FIELD(cw_port, getReal),
    CW_FIELD(cw_port, setReal), CW_FIELD(cw_port, setInputDerivatives),
    CW_FIELD(cw_port, getOutputDerivatives), CW_FIELD(cw_port, getState), CW_FIELD(cw_port, setState),
    CW_FIELD(cw_port, state), CW_FIELD(cw_port, out_vr), CW_FIELD(cw_port, out), CW_FIELD(cw_port, in_vr),
    CW_FIELD(cw_port, inp), CW_FIELD(cw_port, der_vr), CW_FIELD(cw_port, der_order), CW_FIELD(cw_port, der),
    CW_FIELD(cw_port, src_port), CW_FIELD(cw_port, src_pos), CW_FIELD(cw_port, sent),
    CW_FIELD(cw_port, dsrc_port), CW_FIELD(cw_port, dsrc_vr), CW_FIELD(cw_port, dsrc_m),
    CW_FIELD(cw_port, hist_t), CW_FIELD(cw_port, hist_v), CW_FIELD(cw_port, snap_hist_t),
    CW_FIELD(cw_port, snap_hist_v), CW_FIELD(cw_port, scaled), CW_FIELD(cw_port, in_factor),
    CW_FIELD(cw_port, in_offset), CW_FIELD(cw_port, out_time), CW_FIELD(cw_port, lowered_at),
    CW_FIELD(cw_port, n_out), CW_FIELD(cw_port, n_in), CW_FIELD(cw_port, n_z),
    CW_FIELD(cw_port, max_output_derivative_order), CW_FIELD(cw_port, sent_valid), CW_FIELD(cw_port, hist_n),
    CW_FIELD(cw_port, snap_hist_n), CW_FIELD(cw_port, n_scaled), CW_FIELD(cw_port, ext_order),
    CW_FIELD(cw_port, pad_), CW_FIELD(cw_port, it_start), CW_FIELD(cw_port, it_end),
    CW_FIELD(cw_port, can_interpolate), CW_FIELD(cw_port, rate),
    CW_FIELD(cw_port, add_at), CW_FIELD(cw_port, add_port), CW_FIELD(cw_port, add_pos),
    CW_FIELD(cw_port, n_adds), CW_FIELD(cw_port, pad3_),
};
static const cw_field loop_layout[] = {
    CW_FIELD(cw_loop, members), CW_FIELD(cw_loop, u_port), CW_FIELD(cw_loop, u_pos), CW_FIELD(cw_loop, u_src),
    CW_FIELD(cw_loop, u_src_pos), CW_FIELD(cw_loop, u_factor), CW_FIELD(cw_loop, u_offset),
    CW_FIELD(cw_loop, u_scaled), CW_FIELD(cw_loop, r), CW_FIELD(cw_loop, fail_worst),
    CW_FIELD(cw_loop, n_members), CW_FIELD(cw_loop, n), CW_FIELD(cw_loop, fail_why),
    CW_FIELD(cw_loop, fail_at), CW_FIELD(cw_loop, fail_sweeps), CW_FIELD(cw_loop, fail_newton),
};
static const cw_field loops_layout[] = {
    CW_FIELD(cw_loops, loop), CW_FIELD(cw_loops, tolerance), CW_FIELD(cw_loops, iterations),
    CW_FIELD(cw_loops, fallbacks), CW_FIELD(cw_loops, n_loops), CW_FIELD(cw_loops, pad_),
};
static const cw_field master_layout[] = {
    CW_FIELD(cw_master, ports), CW_FIELD(cw_master, first), CW_FIELD(cw_master, dynamic),
    CW_FIELD(cw_master, first_in_order), CW_FIELD(cw_master, final_order), CW_FIELD(cw_master, buffer),
    CW_FIELD(cw_master, z_port), CW_FIELD(cw_master, z_pos), CW_FIELD(cw_master, z_start),
    CW_FIELD(cw_master, z_end), CW_FIELD(cw_master, zs_port), CW_FIELD(cw_master, zs_pos),
    CW_FIELD(cw_master, zs_vr), CW_FIELD(cw_master, prev_kind), CW_FIELD(cw_master, prev_u),
    CW_FIELD(cw_master, prev_du), CW_FIELD(cw_master, amp_u), CW_FIELD(cw_master, amp_du),
    CW_FIELD(cw_master, z_seen), CW_FIELD(cw_master, end_rate_set), CW_FIELD(cw_master, end_rate),
    CW_FIELD(cw_master, snap_z_end), CW_FIELD(cw_master, since), CW_FIELD(cw_master, t),
    CW_FIELD(cw_master, start_time), CW_FIELD(cw_master, step), CW_FIELD(cw_master, event_time_tolerance),
    CW_FIELD(cw_master, event_indicator_tolerance), CW_FIELD(cw_master, divergence_limit),
    CW_FIELD(cw_master, time_to_zero), CW_FIELD(cw_master, step_cap), CW_FIELD(cw_master, located_from),
    CW_FIELD(cw_master, snap_t), CW_FIELD(cw_master, snap_time_to_zero), CW_FIELD(cw_master, err_t),
    CW_FIELD(cw_master, err_h), CW_FIELD(cw_master, steps), CW_FIELD(cw_master, events),
    CW_FIELD(cw_master, event_iterations), CW_FIELD(cw_master, rollbacks), CW_FIELD(cw_master, replays),
    CW_FIELD(cw_master, states_saved), CW_FIELD(cw_master, n_ports), CW_FIELD(cw_master, n_first),
    CW_FIELD(cw_master, n_dynamic), CW_FIELD(cw_master, n_first_in_order), CW_FIELD(cw_master, n_final),
    CW_FIELD(cw_master, n_buffer), CW_FIELD(cw_master, n_z), CW_FIELD(cw_master, cap_since),
    CW_FIELD(cw_master, jacobi), CW_FIELD(cw_master, extrapolation), CW_FIELD(cw_master, locating),
    CW_FIELD(cw_master, has_sources), CW_FIELD(cw_master, after_event), CW_FIELD(cw_master, after_event_step),
    CW_FIELD(cw_master, sample_countdown), CW_FIELD(cw_master, prev_valid),
    CW_FIELD(cw_master, stale_sources), CW_FIELD(cw_master, snap_valid),
    CW_FIELD(cw_master, snap_after_event), CW_FIELD(cw_master, n_since),
    CW_FIELD(cw_master, max_replay_steps), CW_FIELD(cw_master, diverged), CW_FIELD(cw_master, err_port),
    CW_FIELD(cw_master, err_call), CW_FIELD(cw_master, err_status), CW_FIELD(cw_master, orders_lowered),
    CW_FIELD(cw_master, n_fmi3), CW_FIELD(cw_master, pad4_), CW_FIELD(cw_master, fmi3), CW_FIELD(cw_master, pred_kind),
    CW_FIELD(cw_master, pred_u), CW_FIELD(cw_master, pred_du), CW_FIELD(cw_master, pred_ddu),
    CW_FIELD(cw_master, last_z), CW_FIELD(cw_master, sampled_t), CW_FIELD(cw_master, sampled_before_t),
    CW_FIELD(cw_master, last_t), CW_FIELD(cw_master, predicted_landings),
    CW_FIELD(cw_master, mispredicted), CW_FIELD(cw_master, predicting), CW_FIELD(cw_master, last_valid),
    CW_FIELD(cw_master, iteration_tolerance), CW_FIELD(cw_master, coupling_iterations),
    CW_FIELD(cw_master, iterations), CW_FIELD(cw_master, pad3_), CW_FIELD(cw_master, loops),
    CW_FIELD(cw_master, pool), CW_FIELD(cw_master, par_end), CW_FIELD(cw_master, par_status),
    CW_FIELD(cw_master, after_start), CW_FIELD(cw_master, after_order), CW_FIELD(cw_master, inputs),
    CW_FIELD(cw_master, clocks), CW_FIELD(cw_master, rates),
};
static const cw_field clocks_layout[] = {
    CW_FIELD(cw_clocks, next), CW_FIELD(cw_clocks, n_next), CW_FIELD(cw_clocks, asked),
    CW_FIELD(cw_clocks, pending), CW_FIELD(cw_clocks, due),
};
static const cw_field rates_layout[] = {
    CW_FIELD(cw_rates, held_port), CW_FIELD(cw_rates, held_pos), CW_FIELD(cw_rates, src_port),
    CW_FIELD(cw_rates, src_pos), CW_FIELD(cw_rates, every), CW_FIELD(cw_rates, starts), CW_FIELD(cw_rates, count),
    CW_FIELD(cw_rates, n_links), CW_FIELD(cw_rates, pad_),
};
static const cw_field inputs_layout[] = {
    CW_FIELD(cw_inputs, times), CW_FIELD(cw_inputs, values), CW_FIELD(cw_inputs, continuous),
    CW_FIELD(cw_inputs, events), CW_FIELD(cw_inputs, port_start), CW_FIELD(cw_inputs, vr),
    CW_FIELD(cw_inputs, signal), CW_FIELD(cw_inputs, value), CW_FIELD(cw_inputs, after_step), CW_FIELD(cw_inputs, n_times),
    CW_FIELD(cw_inputs, n_signals), CW_FIELD(cw_inputs, n_events), CW_FIELD(cw_inputs, pad_),
};
static const cw_field recorder_layout[] = {
    CW_FIELD(cw_recorder, col_port), CW_FIELD(cw_recorder, col_pos), CW_FIELD(cw_recorder, rows),
    CW_FIELD(cw_recorder, ticks), CW_FIELD(cw_recorder, last_tick), CW_FIELD(cw_recorder, grid_seen),
    CW_FIELD(cw_recorder, grid_k), CW_FIELD(cw_recorder, n_cols), CW_FIELD(cw_recorder, capacity),
    CW_FIELD(cw_recorder, n_rows), CW_FIELD(cw_recorder, tick_capacity), CW_FIELD(cw_recorder, n_ticks),
    CW_FIELD(cw_recorder, stride), CW_FIELD(cw_recorder, tick_port), CW_FIELD(cw_recorder, tick_pos),
    CW_FIELD(cw_recorder, has_interval), CW_FIELD(cw_recorder, pad_),
};
static const cw_field marks_layout[] = {
    CW_FIELD(cw_marks, times), CW_FIELD(cw_marks, sets), CW_FIELD(cw_marks, values), CW_FIELD(cw_marks, in_port),
    CW_FIELD(cw_marks, in_vr), CW_FIELD(cw_marks, out_port), CW_FIELD(cw_marks, out_pos),
    CW_FIELD(cw_marks, prev_port), CW_FIELD(cw_marks, prev_pos), CW_FIELD(cw_marks, previous),
    CW_FIELD(cw_marks, watch_port), CW_FIELD(cw_marks, watch_pos), CW_FIELD(cw_marks, seen),
    CW_FIELD(cw_marks, rows), CW_FIELD(cw_marks, margin), CW_FIELD(cw_marks, max_step),
    CW_FIELD(cw_marks, tolerance), CW_FIELD(cw_marks, period), CW_FIELD(cw_marks, last_event),
    CW_FIELD(cw_marks, prev_event), CW_FIELD(cw_marks, n_times), CW_FIELD(cw_marks, next),
    CW_FIELD(cw_marks, n_in), CW_FIELD(cw_marks, n_out), CW_FIELD(cw_marks, n_prev), CW_FIELD(cw_marks, n_watch),
    CW_FIELD(cw_marks, capacity), CW_FIELD(cw_marks, n_rows), CW_FIELD(cw_marks, follow),
    CW_FIELD(cw_marks, has_prev), CW_FIELD(cw_marks, record), CW_FIELD(cw_marks, stop_at_change),
    CW_FIELD(cw_marks, stopped), CW_FIELD(cw_marks, pad_),
};
static const cw_field fmi3_layout[] = {
    CW_FIELD(cw_fmi3, instance), CW_FIELD(cw_fmi3, doStep), CW_FIELD(cw_fmi3, getFloat64),
    CW_FIELD(cw_fmi3, setFloat64), CW_FIELD(cw_fmi3, getOutputDerivatives), CW_FIELD(cw_fmi3, getState),
    CW_FIELD(cw_fmi3, setState), CW_FIELD(cw_fmi3, enterEventMode), CW_FIELD(cw_fmi3, updateDiscreteStates),
    CW_FIELD(cw_fmi3, enterStepMode), CW_FIELD(cw_fmi3, next_event_time),
    CW_FIELD(cw_fmi3, saved_next_event_time), CW_FIELD(cw_fmi3, end_time),
    CW_FIELD(cw_fmi3, early_returns), CW_FIELD(cw_fmi3, events), CW_FIELD(cw_fmi3, event_mode_used),
    CW_FIELD(cw_fmi3, terminated), CW_FIELD(cw_fmi3, failed_call), CW_FIELD(cw_fmi3, pad_),
    CW_FIELD(cw_fmi3, n_iu), CW_FIELD(cw_fmi3, iu_poly), CW_FIELD(cw_fmi3, iu_vr), CW_FIELD(cw_fmi3, iu_u0),
    CW_FIELD(cw_fmi3, iu_d1), CW_FIELD(cw_fmi3, iu_d2), CW_FIELD(cw_fmi3, iu_tref), CW_FIELD(cw_fmi3, iu_fed),
    CW_FIELD(cw_fmi3, iu_set_vr), CW_FIELD(cw_fmi3, iu_val), CW_FIELD(cw_fmi3, iu_time),
    CW_FIELD(cw_fmi3, iu_saved_time), CW_FIELD(cw_fmi3, iu_calls), CW_FIELD(cw_fmi3, iu_saved),
    CW_FIELD(cw_fmi3, iu_saved_fed), CW_FIELD(cw_fmi3, code_base), CW_FIELD(cw_fmi3, n_codes),
    CW_FIELD(cw_fmi3, code_vr), CW_FIELD(cw_fmi3, code_off), CW_FIELD(cw_fmi3, code_size),
    CW_FIELD(cw_fmi3, scratch_vr), CW_FIELD(cw_fmi3, scratch_order), CW_FIELD(cw_fmi3, scratch_val),
    CW_FIELD(cw_fmi3, scratch_cap), CW_FIELD(cw_fmi3, scratch_val_cap), CW_FIELD(cw_fmi3, clock_event),
};
static const cw_field fmi1_layout[] = {
    CW_FIELD(cw_fmi1, instance), CW_FIELD(cw_fmi1, doStep), CW_FIELD(cw_fmi1, getReal),
    CW_FIELD(cw_fmi1, setReal), CW_FIELD(cw_fmi1, setInputDerivatives),
    CW_FIELD(cw_fmi1, getOutputDerivatives), CW_FIELD(cw_fmi1, negated_vr), CW_FIELD(cw_fmi1, base_vr),
    CW_FIELD(cw_fmi1, time), CW_FIELD(cw_fmi1, zero_steps), CW_FIELD(cw_fmi1, n_negated),
    CW_FIELD(cw_fmi1, stale), CW_FIELD(cw_fmi1, failed_zero), CW_FIELD(cw_fmi1, pad_),
};

CW_EXPORT const cw_field *cw_layout(const char *name, size_t *n_fields, size_t *struct_size)
{
    CW_LAYOUT_CASE(port)
    CW_LAYOUT_CASE(loop)
    CW_LAYOUT_CASE(loops)
    CW_LAYOUT_CASE(master)
    CW_LAYOUT_CASE(inputs)
    CW_LAYOUT_CASE(clocks)
    CW_LAYOUT_CASE(rates)
    CW_LAYOUT_CASE(recorder)
    CW_LAYOUT_CASE(marks)
    CW_LAYOUT_CASE(fmi3)
    CW_LAYOUT_CASE(fmi1)
    *n_fields = 0;
    *struct_size = 0;
    return NULL;
}

static const cw_field sundials_layout[] = {
    CW_FIELD(cw_sundials, SUNContext_Create), CW_FIELD(cw_sundials, SUNContext_Free),
    CW_FIELD(cw_sundials, SUNContext_ClearErrHandlers), CW_FIELD(cw_sundials, N_VGetArrayPointer),
    CW_FIELD(cw_sundials, N_VDestroy), CW_FIELD(cw_sundials, SUNMatDestroy),
    CW_FIELD(cw_sundials, SUNLinSolFree), CW_FIELD(cw_sundials, N_VNew_Serial),
    CW_FIELD(cw_sundials, SUNDenseMatrix), CW_FIELD(cw_sundials, SUNLinSol_Dense),
    CW_FIELD(cw_sundials, CVodeCreate), CW_FIELD(cw_sundials, CVodeInit), CW_FIELD(cw_sundials, CVodeReInit),
    CW_FIELD(cw_sundials, CVodeSVtolerances), CW_FIELD(cw_sundials, CVodeSetLinearSolver),
    CW_FIELD(cw_sundials, CVodeSetUserData), CW_FIELD(cw_sundials, CVodeSetStopTime),
    CW_FIELD(cw_sundials, CVode), CW_FIELD(cw_sundials, CVodeGetDky),
    CW_FIELD(cw_sundials, CVodeGetNumRhsEvals), CW_FIELD(cw_sundials, CVodeGetNumLinRhsEvals),
    CW_FIELD(cw_sundials, CVodeGetNumErrTestFails), CW_FIELD(cw_sundials, CVodeGetNumNonlinSolvConvFails),
    CW_FIELD(cw_sundials, CVodeFree),
};
static const cw_field me_layout[] = {
    CW_FIELD(cw_me, instance), CW_FIELD(cw_me, setTime), CW_FIELD(cw_me, setStates),
    CW_FIELD(cw_me, getDerivatives), CW_FIELD(cw_me, getIndicators), CW_FIELD(cw_me, getStates),
    CW_FIELD(cw_me, getNominals), CW_FIELD(cw_me, completedStep), CW_FIELD(cw_me, enterEventMode),
    CW_FIELD(cw_me, update), CW_FIELD(cw_me, enterContinuousMode), CW_FIELD(cw_me, getReal),
    CW_FIELD(cw_me, setReal), CW_FIELD(cw_me, getState), CW_FIELD(cw_me, setState), CW_FIELD(cw_me, calls),
    CW_FIELD(cw_me, sundials),
    CW_FIELD(cw_me, rk), CW_FIELD(cw_me, x), CW_FIELD(cw_me, xbuf), CW_FIELD(cw_me, xw), CW_FIELD(cw_me, xd),
    CW_FIELD(cw_me, dx), CW_FIELD(cw_me, nominal), CW_FIELD(cw_me, atolv), CW_FIELD(cw_me, z_prev),
    CW_FIELD(cw_me, z), CW_FIELD(cw_me, z_end), CW_FIELD(cw_me, z_lo), CW_FIELD(cw_me, z0),
    CW_FIELD(cw_me, in_vr), CW_FIELD(cw_me, u0), CW_FIELD(cw_me, d1), CW_FIELD(cw_me, d2),
    CW_FIELD(cw_me, tref), CW_FIELD(cw_me, in_val), CW_FIELD(cw_me, state_vr), CW_FIELD(cw_me, der_state),
    CW_FIELD(cw_me, saved), CW_FIELD(cw_me, cv_mem), CW_FIELD(cw_me, cv_ctx), CW_FIELD(cw_me, cv_y),
    CW_FIELD(cw_me, cv_abstol), CW_FIELD(cw_me, cv_dky), CW_FIELD(cw_me, cv_A), CW_FIELD(cw_me, cv_LS),
    CW_FIELD(cw_me, time), CW_FIELD(cw_me, next_event_time), CW_FIELD(cw_me, end_time), CW_FIELD(cw_me, rtol),
    CW_FIELD(cw_me, event_time_tolerance), CW_FIELD(cw_me, h_next), CW_FIELD(cw_me, err_t),
    CW_FIELD(cw_me, saved_time), CW_FIELD(cw_me, saved_next_event_time), CW_FIELD(cw_me, saved_end_time),
    CW_FIELD(cw_me, saved_h_next), CW_FIELD(cw_me, steps), CW_FIELD(cw_me, rejected),
    CW_FIELD(cw_me, rhs), CW_FIELD(cw_me, state_events), CW_FIELD(cw_me, time_events),
    CW_FIELD(cw_me, step_events), CW_FIELD(cw_me, input_events), CW_FIELD(cw_me, event_iterations),
    CW_FIELD(cw_me, switches), CW_FIELD(cw_me, n), CW_FIELD(cw_me, nz),
    CW_FIELD(cw_me, n_in), CW_FIELD(cw_me, solver), CW_FIELD(cw_me, method), CW_FIELD(cw_me, stiff_count),
    CW_FIELD(cw_me, nonstiff_count), CW_FIELD(cw_me, terminated), CW_FIELD(cw_me, mode),
    CW_FIELD(cw_me, poly), CW_FIELD(cw_me, inputs_dirty), CW_FIELD(cw_me, restart), CW_FIELD(cw_me, cv_owner),
    CW_FIELD(cw_me, failed_call), CW_FIELD(cw_me, failed_status), CW_FIELD(cw_me, failed_detail),
    CW_FIELD(cw_me, needs_completed), CW_FIELD(cw_me, saved_method), CW_FIELD(cw_me, saved_stiff_count),
    CW_FIELD(cw_me, saved_nonstiff_count), CW_FIELD(cw_me, saved_terminated), CW_FIELD(cw_me, saved_poly),
    CW_FIELD(cw_me, saved_mode), CW_FIELD(cw_me, pad4_),
};

static const cw_field me_group_layout[] = {
    CW_FIELD(cw_me_group, me), CW_FIELD(cw_me_group, members), CW_FIELD(cw_me_group, member_state),
    CW_FIELD(cw_me_group, offsets), CW_FIELD(cw_me_group, vr_member), CW_FIELD(cw_me_group, vr_own),
    CW_FIELD(cw_me_group, c_src), CW_FIELD(cw_me_group, c_dst), CW_FIELD(cw_me_group, c_src_vr),
    CW_FIELD(cw_me_group, c_dst_vr), CW_FIELD(cw_me_group, c_continuous), CW_FIELD(cw_me_group, c_identity),
    CW_FIELD(cw_me_group, c_factor), CW_FIELD(cw_me_group, c_offset), CW_FIELD(cw_me_group, c_last),
    CW_FIELD(cw_me_group, c_has_last), CW_FIELD(cw_me_group, c_get), CW_FIELD(cw_me_group, c_set),
    CW_FIELD(cw_me_group, c_get_shape), CW_FIELD(cw_me_group, c_set_shape), CW_FIELD(cw_me_group, c_last_int),
    CW_FIELD(cw_me_group, n_members), CW_FIELD(cw_me_group, n_conns),
    CW_FIELD(cw_me_group, dirty), CW_FIELD(cw_me_group, pad_),
};

CW_EXPORT const cw_field *cwme_layout(const char *name, size_t *n_fields, size_t *struct_size)
{
    CW_LAYOUT_CASE(sundials)
    CW_LAYOUT_CASE(me)
    CW_LAYOUT_CASE(me_group)
    *n_fields = 0;
    *struct_size = 0;
    return NULL;
}
