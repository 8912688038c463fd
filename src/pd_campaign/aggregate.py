"""The campaign's trial rows aggregated: per case and speed (summarise: success with its Wilson 95 %
interval, medians and quartiles, the field's metrics, the pairing with the stationary case), per
volunteer (the H1 stops), per injected fault (fault_summary); how a trial stopped (stop_line);
summary.json. Computed from the rows alone, so a merge of shards gives the same."""
import json

from . import stats
from .atomic import atomic_write
from .design import CASES, FAULTS

def quartile_values(values):
    """[first quartile, median, third quartile] (linear interpolation), None if empty."""
    values = sorted(v for v in values if v is not None)
    if not values:
        return None

    def q(p):
        x = p * (len(values) - 1)
        i = int(x)
        return values[i] + (values[min(i + 1, len(values) - 1)] - values[i]) * (x - i)
    return [q(0.25), q(0.5), q(0.75)]


def summarise(rows):
    """Per case and rpm: trials, successes, success rate with its Wilson 95 % interval, medians.
    Trials with an injected fault are left out (fault_summary reports them)."""
    groups = {}
    for row in rows:
        if (row.get('fault') or 'none') != 'none':
            continue
        groups.setdefault((row['case'], row['rpm']), []).append(row)
    summary = []
    for (case, rpm), group in sorted(groups.items(),
                                     key=lambda kv: (kv[0][1], CASES.index(kv[0][0])
                                                     if kv[0][0] in CASES else 9)):
        valid = [r for r in group if not r.get('error')]
        successes = sum(1 for r in valid if r['success'])
        low, high = stats.wilson_interval(successes, len(valid))
        summary.append({
            'case': case,
            'rpm': rpm,
            'trials': len(valid),
            'errors': len(group) - len(valid),
            'successes': successes,
            'success_rate': successes / len(valid) if valid else None,
            'wilson95': [low, high],
            'median_f_out_n': stats.median([r['f_out_n'] for r in valid]),
            'median_f_in_n': stats.median([r['f_in_n'] for r in valid]),
            'quartiles_f_out_n': quartile_values([r['f_out_n'] for r in valid]),
            'quartiles_f_in_n': quartile_values([r['f_in_n'] for r in valid]),
            'defined_f_in': sum(1 for r in valid if r['f_in_n'] is not None),
            'median_f_out_truth_n': stats.median([r.get('f_out_truth_n') for r in valid]),
            'median_f_in_truth_n': stats.median([r.get('f_in_truth_n') for r in valid]),
            'median_residual_mm_successful': stats.median(
                [r['residual_mm'] for r in valid if r['success']]),
            'median_tracking_rms_mm': stats.median([r['tracking_rms_mm'] for r in valid]),
            'median_contact_loss_count': stats.median(
                [r.get('contact_loss_count') for r in valid]),
            'stop_reasons': count(stop_category(r) for r in valid),
            'outcomes': count(outcome(r) for r in valid),
            'median_tracking_rms_mm_failures': stats.median(
                [r['tracking_rms_mm'] for r in valid if not r['success']]),
        })
        summary[-1].update(field_metrics(valid))
    # Moving cases against the stationary case on the same specimens (seeds are paired across
    # cases, design.py): McNemar's exact test on the discordant pairs.
    for g in summary:
        base = groups.get(('stationary', g['rpm']))
        if g['case'] == 'stationary' or base is None:
            continue
        n, both, only_case, only_stationary, neither = stats.paired_counts(
            groups[(g['case'], g['rpm'])], base, key=lambda r: r['seed'])
        g['paired_vs_stationary'] = {
            'pairs': n, 'both': both, 'only_this_case': only_case,
            'only_stationary': only_stationary, 'neither': neither,
            'mcnemar_p': stats.mcnemar_exact(only_case, only_stationary)}
    return summary


def field_metrics(valid):
    """The field's metrics of a group of trials (Xia et al. 2024 report correct stops
    and no penetration separately): correct-stop and no-penetration rates with Wilson 95 %
    intervals, the failure kinds, and the medians (with quartiles) of the stop's distance from
    the inner layer's end, the overshoot past the layer's entry and the detection latency
    (pd_campaign.outcome defines each)."""
    n = len(valid)
    correct = sum(1 for r in valid if r['success'])
    intact = sum(1 for r in valid if not r['breakthrough'])
    return {
        'correct_stop_rate': correct / n if n else None,
        'correct_stop_wilson95': list(stats.wilson_interval(correct, n)),
        'no_penetration': intact,
        'no_penetration_rate': intact / n if n else None,
        'no_penetration_wilson95': list(stats.wilson_interval(intact, n)),
        'failure_kinds': count(r.get('failure_kind') or outcome(r) for r in valid),
        'quartiles_stop_residual_mm': quartile_values([r.get('stop_residual_mm') for r in valid]),
        'quartiles_overshoot_mm': quartile_values([r.get('overshoot_mm') for r in valid]),
        'quartiles_detection_latency_ms': quartile_values(
            [r.get('detection_latency_ms') for r in valid]),
    }


def h1_by_volunteer(rows):
    """The monitor's H1 stops (bone position error) per case and virtual volunteer, with the
    prediction error they reported (trials without a fault). Empty when there was none."""
    groups = {}
    for row in rows:
        if (row.get('fault') or 'none') != 'none' or row.get('error'):
            continue
        key = (row['case'], row['rpm'], row.get('volunteer_id'))
        groups.setdefault(key, []).append(row)
    out = []
    for (case, rpm, volunteer), group in sorted(groups.items(), key=lambda kv: (
            kv[0][1], CASES.index(kv[0][0]) if kv[0][0] in CASES else 9, str(kv[0][2]))):
        h1 = [r for r in group if (r.get('first_stop_kind') or r.get('failure_kind'))
              == 'safety_h1']
        out.append({'case': case, 'rpm': rpm, 'volunteer_id': volunteer, 'trials': len(group),
                    'h1_stops': len(h1),
                    'quartiles_h1_error_mm': quartile_values([r.get('h1_error_mm') for r in h1]),
                    'max_h1_error_mm': maximum([r.get('h1_error_mm') for r in h1])})
    return out if any(g['h1_stops'] for g in out) else []


def maximum(values):
    values = [v for v in values if v is not None]
    return max(values) if values else None


def minimum(values):
    values = [v for v in values if v is not None]
    return min(values) if values else None


def fault_summary(rows):
    """Per case, rpm and fault (fault campaigns): trials, the faults injected, breakthroughs of
    the inner cortical layer, who stopped the drill, fault-to-stop and fault-to-retreat delays,
    and the residual thickness left. Empty when no trial had a fault."""
    if all((r.get('fault') or 'none') == 'none' for r in rows):
        return []
    groups = {}
    for row in rows:
        groups.setdefault((row['case'], row['rpm'], row.get('fault') or 'none'), []).append(row)
    out = []
    for (case, rpm, fault), group in sorted(groups.items(), key=lambda kv: (
            kv[0][1], CASES.index(kv[0][0]) if kv[0][0] in CASES else 9,
            FAULTS.index(kv[0][2]) if kv[0][2] in FAULTS else len(FAULTS))):
        valid = [r for r in group if not r.get('error')]
        injected = [r for r in valid if fault == 'none' or r.get('fault_time_s') is not None]
        stopped = [r for r in injected if r.get('stop_delay_s') is not None]
        retreated = [r for r in injected if r.get('retreat_delay_s') is not None]
        breakthroughs = sum(1 for r in valid if r['breakthrough'])
        low, high = stats.wilson_interval(breakthroughs, len(valid))
        out.append({
            'case': case, 'rpm': rpm, 'fault': fault,
            'trials': len(valid), 'errors': len(group) - len(valid),
            'injected': len(injected) if fault != 'none' else None,
            'breakthroughs': breakthroughs, 'breakthrough_wilson95': [low, high],
            'successes': sum(1 for r in valid if r['success']),
            'stopped_after_fault': len(stopped) if fault != 'none' else None,
            'retreated_after_fault': len(retreated) if fault != 'none' else None,
            'median_stop_delay_s': stats.median([r['stop_delay_s'] for r in stopped]),
            'max_stop_delay_s': maximum([r['stop_delay_s'] for r in stopped]),
            'median_retreat_delay_s': stats.median([r['retreat_delay_s'] for r in retreated]),
            'max_retreat_delay_s': maximum([r['retreat_delay_s'] for r in retreated]),
            'median_residual_mm': stats.median([r['residual_mm'] for r in valid]),
            'min_residual_mm': minimum([r['residual_mm'] for r in valid]),
            'stop_reasons': count(stop_category(r) for r in injected),
            'failure_kinds': count(r.get('failure_kind') or outcome(r) for r in valid),
            'drift_detected': sum(1 for r in valid if r.get('drift_detected')),
        })
    return out


def stop_category(row):
    """Who stopped the drill and why, without the per-trial details of the message."""
    source = (row.get('stop_source') or '').rsplit('/', 1)[-1]
    reason = row.get('stop_reason') or ''
    if source == 'state_recognizer':
        return 'recognizer'
    if source == 'safety_monitor':
        return 'safety: ' + reason.split(':', 1)[0]
    if source == 'compensation_planner':
        return 'planner: ' + reason.split(':', 1)[0]
    if source == 'protocol':
        return 'protocol'
    if source in ('drill_guard', 'drive_guard'):  # a lost process: the drives hold
        return source.replace('_', ' ') + ': ' + reason.split(':', 1)[0]
    return 'no stop (%s)' % (reason or 'max_duration')


STOP_LINES = ('recognizer', 'plausibility bound', 'depth limit', 'safety monitor', 'other',
              'no stop')


def stop_line(row):
    """Which line of defence made the trial's first stop: the recognizer (the primary stop), the
    planner's plausibility bound on the recognizer's layers, the plan's depth limit, the safety
    monitor (its checks and its drill guard), another stop (a silent component, the protocol),
    or none."""
    source = (row.get('stop_source') or '').rsplit('/', 1)[-1]
    reason = row.get('stop_reason') or ''
    if source == 'state_recognizer':
        return 'recognizer'
    if reason.startswith('depth_limit'):
        return 'depth limit'
    if 'implausible' in reason:
        return 'plausibility bound'
    if source in ('safety_monitor', 'drill_guard', 'drive_guard'):
        return 'safety monitor'
    if source in ('', 'none'):
        return 'no stop'
    return 'other'


def outcome(row):
    """Where the drill ended relative to the inner cortical layer (simulator ground truth)."""
    if row['success']:
        return 'success'
    if row.get('breakthrough'):
        return 'breakthrough'
    depth, inner_start = row.get('max_depth_mm'), row.get('inner_start_mm')
    if depth is not None and inner_start is not None and depth <= inner_start:
        return 'stopped before the inner cortical layer'
    residual = row.get('residual_mm')
    if residual is not None and residual > 2.0:
        return 'inside the inner layer, residual > 2 mm'
    return 'other'


def count(items):
    counts = {}
    for item in items:
        counts[item] = counts.get(item, 0) + 1
    return dict(sorted(counts.items()))


def write_summary_json(summary, meta, path, faults=None):
    content = {'meta': meta, 'groups': summary}
    if faults:
        content['faults'] = faults
    with atomic_write(path) as handle:
        json.dump(content, handle, indent=2, sort_keys=True)
        handle.write('\n')
