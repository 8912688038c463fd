"""Why a trial ended as it did: its failure kind and the field's metrics, from what
both engines record (the ground-truth stream, the stop commands). Pure functions of the record.

Failure kinds, one per trial, the first that applies:
  success                  the paper's success (recognizer stop inside the inner cortical layer,
                           residual in (0, 2 mm], no breakthrough)
  breakthrough_before_stop the inner cortical layer was perforated before the first stop command
                           (or with no stop command at all)
  breakthrough_after_stop  ... after it (spindle run-down, or the bone moving into the held drill)
  no_stop                  no stop command at all, no breakthrough (the trial ran to its maximum
                           duration)
  safety_h1                the first stop was the monitor's position error (> 1.2 mm)
  safety_h2                ... the monitor's force limit (> 10 N)
  safety_watchdog          ... a silent, stale, stuck or non-finite stream (monitor or planner),
                           a lost prediction, or the drill guard (a lost process: the drives
                           hold)
  safety_plausibility      ... an implausible force (recognizer or planner plausibility bound)
  safety_depth_limit       ... the planner's depth limit (the plan's depth reached)
  safety_other             ... any other stop with retreat (the peak-force protocol included)
  stopped_before_inner     the recognizer stopped the drill before it reached the inner layer
  stopped_shallow          ... inside the inner layer with more than 2 mm of it left

Metrics (mm below the bone surface along the drill, ms of sim time):
  stop_depth_mm         deepest cut when the first stop command was sent
  stop_residual_mm      inner cortex left below that cut (the stop's distance from the layer's
                        end; more than the layer's thickness when it was not reached)
  overshoot_mm          deepest cut at the end of the trial minus the depth of the inner layer's
                        entry (the ideal stop point: the earliest at which a force recognizer can
                        know it is in the inner cortex); None when the layer was not entered
  rundown_mm            deepest cut at the end minus at the first stop command
  detection_latency_ms  first stop command minus the moment the deepest cut entered the inner
                        layer; negative when the layer was entered only after the stop command
                        (run-down); None when it was never entered, or no stop
"""

import re

KINDS = ('success', 'breakthrough_before_stop', 'breakthrough_after_stop', 'no_stop',
         'safety_h1', 'safety_h2', 'safety_watchdog', 'safety_plausibility',
         'safety_depth_limit', 'safety_other',
         'stopped_before_inner', 'stopped_shallow')
SAFETY_KINDS = tuple(k for k in KINDS if k.startswith('safety_'))
# The paper's success band: residual thickness of the inner cortex in (0, 2 mm] (Sec. V-C/E).
MAX_RESIDUAL_M = 2.0e-3
_WATCHDOG = ('force_timeout', 'tracker_timeout', 'nan_input', 'force_stuck', 'silent',
             'prediction_lost', 'planner_lost', 'stop_unanswered', 'drive_guard')
_H1_ERROR = re.compile(r'position error ([0-9.]+) mm')


def stop_kind(stop):
    """The safety kind of a stop (t, source, reason, retreat), or None for the recognizer's own
    inner-layer stop."""
    _, source, reason, retreat = stop[:4]
    if reason.startswith('depth_limit'):
        return 'safety_depth_limit'
    if 'implausible' in reason:
        return 'safety_plausibility'
    if source.endswith('safety_monitor'):
        if reason.startswith('position_error'):
            return 'safety_h1'
        if reason.startswith('force_exceeded'):
            return 'safety_h2'
        return 'safety_watchdog'
    if any(word in reason for word in _WATCHDOG):
        return 'safety_watchdog'
    if retreat:
        return 'safety_other'
    return None


def first_stop_kind(stops):
    """The safety kind of the first stop command (stop_kind), or None."""
    return stop_kind(stops[0]) if stops else None


def h1_error_mm(reason):
    """The bone position error (mm) an H1 stop reports, or None."""
    match = _H1_ERROR.search(reason or '')
    return float(match.group(1)) if match else None


def _at_or_before(truth, t):
    """The last ground-truth row at or before t (None if none)."""
    last = None
    for row in truth:
        if row[0] > t + 1e-9:
            break
        last = row
    return last


def classify(truth, stops, inner_start_m, success):
    """(failure kind, metrics dict) of a trial. `truth`: ground-truth rows (t, layer, max_depth,
    residual, breakthrough, ...) in time order from the start of drilling; `stops`: the stop
    commands (t, source, reason, retreat) in time order; `inner_start_m`: depth of the inner
    cortical layer's entry; `success`: the paper's criterion, judged by the caller."""
    stop = stops[0] if stops else None
    metrics = {key: None for key in ('stop_depth_mm', 'stop_residual_mm', 'overshoot_mm',
                                     'rundown_mm', 'detection_latency_ms')}
    final = truth[-1] if truth else None
    t_enter = next((r[0] for r in truth
                    if r[1] == 'inner_cortical' or r[2] > inner_start_m), None)
    t_break = next((r[0] for r in truth if r[4]), None)
    at_stop = _at_or_before(truth, stop[0]) if stop and truth else None
    if final is not None and t_enter is not None:
        metrics['overshoot_mm'] = (final[2] - inner_start_m) * 1e3
    if at_stop is not None:
        metrics['stop_depth_mm'] = at_stop[2] * 1e3
        metrics['stop_residual_mm'] = at_stop[3] * 1e3
        metrics['rundown_mm'] = (final[2] - at_stop[2]) * 1e3
    if stop is not None and t_enter is not None:
        metrics['detection_latency_ms'] = (stop[0] - t_enter) * 1e3
    if success:
        return 'success', metrics
    if t_break is not None:
        return ('breakthrough_before_stop' if stop is None or t_break <= stop[0] + 1e-9
                else 'breakthrough_after_stop'), metrics
    if stop is None:
        return 'no_stop', metrics
    kind = stop_kind(stop)
    if kind is not None:
        return kind, metrics
    depth = final[2] if final is not None else 0.0
    residual = final[3] if final is not None else float('inf')
    if depth <= inner_start_m:
        return 'stopped_before_inner', metrics
    if residual > MAX_RESIDUAL_M:
        return 'stopped_shallow', metrics
    # A recognizer stop in the band that the caller did not call a success (it should not
    # happen; kept visible rather than hidden in another kind).
    return 'safety_other', metrics
