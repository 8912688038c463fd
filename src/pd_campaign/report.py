"""A campaign's report.md (and the peak-force protocol's), from the aggregated rows (aggregate.py);
the paper's numbers it compares against. The trial rows are trials_csv.py's, the figures plots.py's.

Everything here is computed from the trial rows (and per-trial traces) alone, so a merge of
shard directories produces the same report as a single run with the same design."""
from . import stats
from .aggregate import STOP_LINES, h1_by_volunteer, stop_line
from .atomic import atomic_write

PAPER_TABLE_III = {'stationary': (19, 20), 'uncompensated': (13, 20), 'compensated': (19, 20)}
# Fig. 15 (Sec. V-C), compensated case: "from 90 % to 50 % ... 40 %". The paper ran 96
# experiments over nine cells (about 10.7 each) and gives no per-cell count; 10 trials per cell
# is the reading consistent with those rates (9/10, 5/10, 4/10). The other cases are given only
# as "highest" / "decrease", so no count is compared for them.
PAPER_FIG15_COUNTS = {'compensated': {12000.0: (9, 10), 16000.0: (5, 10), 20000.0: (4, 10)}}
# Paper Sec. V-D (Fig. 16, 12000 rpm): median peak force of a case minus the stationary one, N.
PAPER_PEAK_DIFFERENCES = {'uncompensated': (-1.2, -1.43), 'compensated': (-0.43, -0.01)}


def metrics_table(summary):
    """The field's metrics per case and speed (field_metrics)."""
    lines = ['| case | rpm | correct stops (Wilson 95 %) | no penetration (Wilson 95 %) '
             '| stop to the layer\'s end [mm] | overshoot past the entry [mm] '
             '| detection latency [ms] | failure kinds |',
             '|---|---|---|---|---|---|---|---|']
    for g in summary:
        lines.append('| %s | %.0f | %d/%d (%s-%s) | %d/%d (%s-%s) | %s | %s | %s | %s |' % (
            g['case'], g['rpm'], g['successes'], g['trials'], _pct(g['correct_stop_wilson95'][0]),
            _pct(g['correct_stop_wilson95'][1]), g['no_penetration'], g['trials'],
            _pct(g['no_penetration_wilson95'][0]), _pct(g['no_penetration_wilson95'][1]),
            _quartiles(g['quartiles_stop_residual_mm']), _quartiles(g['quartiles_overshoot_mm']),
            _quartiles(g['quartiles_detection_latency_ms'], '%.0f'),
            ', '.join('%s %d' % kv for kv in g['failure_kinds'].items() if kv[0] != 'success')
            or '-'))
    return '\n'.join(lines)


def h1_table(groups):
    """The H1 stops per volunteer (h1_by_volunteer)."""
    lines = ['| case | rpm | volunteer | trials | H1 stops | share | position error at the stop: '
             'quartiles / max [mm] |', '|---|---|---|---|---|---|---|']
    for g in groups:
        if g['case'] == 'stationary':
            continue
        lines.append('| %s | %.0f | %s | %d | %d | %s | %s / %s |' % (
            g['case'], g['rpm'], _volunteer_label(g['volunteer_id']), g['trials'], g['h1_stops'],
            _pct(g['h1_stops'] / g['trials'] if g['trials'] else None),
            _quartiles(g['quartiles_h1_error_mm']), _num(g['max_h1_error_mm'])))
    return '\n'.join(lines)


def h1_section(rows):
    """The report's section of the H1 stops per volunteer (h1_table), as lines; none when no
    trial had an H1 stop."""
    h1 = h1_by_volunteer(rows or [])
    if not h1:
        return []
    return ['## Safety stops H1 per virtual volunteer', '',
            'The monitor\'s H1 stops (tracked bone position against the prediction, > 1.2 mm) of '
            'the moving cases, per virtual volunteer, with the position error each reported (the '
            'prediction error that caused it).', '', h1_table(h1), '']


def _volunteer_label(value):
    if value is None:
        return '-'
    try:
        return '%d' % int(float(value))
    except (TypeError, ValueError):
        return str(value)


def fault_table(faults):
    """The fault campaign's table (doc/experiments.md, "Fault campaign")."""
    lines = ['| case | rpm | fault | trials | injected | breakthroughs (Wilson 95 % upper) '
             '| stopped / retreated after the fault | fault to stop: median / max [s] '
             '| fault to retreat: median / max [s] | residual: median / min [mm] | stops '
             '| failure kinds | sensor drift at the re-tare check |',
             '|---|---|---|---|---|---|---|---|---|---|---|---|---|']
    for g in faults:
        none = g['fault'] == 'none'
        lines.append('| %s | %.0f | %s | %d%s | %s | %d (%s) | %s | %s / %s | %s / %s | %s / %s '
                     '| %s | %s | %d |' % (
                         g['case'], g['rpm'], g['fault'], g['trials'],
                         ' (+%d errored)' % g['errors'] if g['errors'] else '',
                         '-' if none else '%d' % g['injected'], g['breakthroughs'],
                         _pct(g['breakthrough_wilson95'][1]),
                         '-' if none else '%d / %d' % (g['stopped_after_fault'],
                                                       g['retreated_after_fault']),
                         _num(g['median_stop_delay_s'], '%.3f'),
                         _num(g['max_stop_delay_s'], '%.3f'),
                         _num(g['median_retreat_delay_s'], '%.3f'),
                         _num(g['max_retreat_delay_s'], '%.3f'),
                         _num(g['median_residual_mm']), _num(g['min_residual_mm']),
                         ', '.join('%s %d' % kv for kv in g['stop_reasons'].items()),
                         ', '.join('%s %d' % kv for kv in g.get('failure_kinds', {}).items()),
                         g.get('drift_detected', 0)))
    return '\n'.join(lines)


def stop_line_table(rows):
    """Per case and speed, how many trials each line of defence stopped first (stop_line)."""
    groups = {}
    for row in rows:
        if row.get('error'):
            continue
        key = (row.get('case'), float(row.get('rpm') or 0.0))
        groups.setdefault(key, {line: 0 for line in STOP_LINES})[stop_line(row)] += 1
    lines = ['| case | rpm | ' + ' | '.join(STOP_LINES) + ' |',
             '|---|---|' + '---|' * len(STOP_LINES)]
    for (case, rpm), counts in sorted(groups.items(), key=lambda kv: (str(kv[0][0]), kv[0][1])):
        lines.append('| %s | %.0f | %s |' % (case, rpm,
                                             ' | '.join(str(counts[l]) for l in STOP_LINES)))
    return '\n'.join(lines)


def _pct(x):
    return '-' if x is None else '%.0f %%' % (100 * x)


def _num(x, fmt='%.2f'):
    return '-' if x is None else fmt % x


def markdown_table(summary):
    lines = ['| case | rpm | successes | rate | Wilson 95 % | median F_out [N] | median F_in [N] '
             '| median residual (successes) [mm] | median tracking RMS [mm] '
             '| median contact losses | stops |',
             '|---|---|---|---|---|---|---|---|---|---|---|']
    for g in summary:
        errors = ' (+%d errored, not counted)' % g['errors'] if g.get('errors') else ''
        lines.append('| %s | %.0f | %d/%d%s | %s | %s-%s | %s | %s | %s | %s | %s | %s |' % (
            g['case'], g['rpm'], g['successes'], g['trials'], errors, _pct(g['success_rate']),
            _pct(g['wilson95'][0]), _pct(g['wilson95'][1]), _num(g['median_f_out_n']),
            _num(g['median_f_in_n']), _num(g['median_residual_mm_successful']),
            _num(g['median_tracking_rms_mm']), _num(g.get('median_contact_loss_count')),
            ', '.join('%s %d' % kv for kv in g['stop_reasons'].items())))
    return '\n'.join(lines)


def failure_table(summary):
    """Why trials failed: where the drill ended, and the tracking of failures vs all."""
    lines = ['| case | rpm | outcomes (ground truth) | median tracking RMS, failures [mm] |',
             '|---|---|---|---|']
    for g in summary:
        lines.append('| %s | %.0f | %s | %s |' % (
            g['case'], g['rpm'], ', '.join('%s %d' % kv for kv in g['outcomes'].items()),
            _num(g['median_tracking_rms_mm_failures'])))
    return '\n'.join(lines)


def _dominant(counts, exclude=()):
    items = [(n, k) for k, n in counts.items() if k not in exclude]
    return max(items) if items else (0, None)


def analysis(summary):
    """Sentences computed from the summary: where a case falls short of the stationary case (the
    bar the paper sets for compensation) and of the paper, and what the failures have in common.
    The causes behind them are discussed in doc/campaign_results.md ("Results of make run")."""
    by_key = {(g['case'], g['rpm']): g for g in summary}
    lines = []
    for rpm in sorted({g['rpm'] for g in summary}):
        base = by_key.get(('stationary', rpm))
        for case in ('uncompensated', 'compensated'):
            g = by_key.get((case, rpm))
            if g is None or not g['trials']:
                continue
            text = '* %s, %.0f rpm: %d/%d (Wilson 95 %% %s-%s)' % (
                case, rpm, g['successes'], g['trials'], _pct(g['wilson95'][0]),
                _pct(g['wilson95'][1]))
            if base is not None and base['trials']:
                text += ' against stationary %d/%d' % (base['successes'], base['trials'])
                if g['wilson95'][1] < base['wilson95'][0]:
                    text += ', clearly below it (the intervals do not overlap)'
                elif g['successes'] * base['trials'] < base['successes'] * g['trials']:
                    text += ', below it but within the statistical spread'
                else:
                    text += ', as good'
                paired = g.get('paired_vs_stationary')
                if paired and paired['pairs']:
                    text += ('; on the same %d specimens %d succeed only in this case, %d only '
                             'stationary (McNemar exact p = %.3g)' % (
                                 paired['pairs'], paired['only_this_case'],
                                 paired['only_stationary'], paired['mcnemar_p']))
            failures = g['trials'] - g['successes']
            if failures:
                count, where = _dominant(g['outcomes'], exclude=('success',))
                text += '. %d of %d failures: %s' % (count, failures, where)
                stops = _dominant(g['stop_reasons'])[1]
                if stops:
                    text += '; most common stop: %s' % stops
                if g.get('median_tracking_rms_mm_failures') is not None:
                    text += '; median tip-bone AP tracking RMS of the failures %.2f mm' % (
                        g['median_tracking_rms_mm_failures'])
            lines.append(text + '.')
    base = by_key.get(('stationary', 12000.0))
    if base and base['median_f_out_n'] is not None and base['median_f_in_n'] is not None:
        for case, (paper_out, paper_in) in sorted(PAPER_PEAK_DIFFERENCES.items()):
            g = by_key.get((case, 12000.0))
            if not g or g['median_f_out_n'] is None or g['median_f_in_n'] is None:
                continue
            lines.append('* Median peak forces, %s minus stationary at 12000 rpm: F_out %+.2f N, '
                         'F_in %+.2f N (paper Fig. 16: %+.2f N, %+.2f N).' % (
                             case, g['median_f_out_n'] - base['median_f_out_n'],
                             g['median_f_in_n'] - base['median_f_in_n'], paper_out, paper_in))
    if not lines:
        return ''
    return '\n'.join(['## What the numbers say', '',
                      'Computed from the table above; the causes behind the shortfalls are '
                      'analysed in doc/campaign_results.md ("Results of make run").', ''] + lines)


def bone_motion_sentence(meta):
    """What the SPMS played in the moving cases, the prediction model and the profile."""
    profile = meta.get('compensation_profile', 'paper')
    text = _bone_motion(meta)
    planner = meta.get('planner_params') or {}
    if planner:
        text += ' Planner parameters: %s.' % ', '.join(
            '%s = %s' % kv for kv in sorted(planner.items()))
    delays = meta.get('engine_delays') or {}
    if delays:
        text += ' Engine delays: %s.' % ', '.join('%s = %s' % kv for kv in sorted(delays.items()))
    if profile == 'exact':
        return text + (' Compensation profile: exact (beyond the paper: the predicted reference '
                       'streamed with its analytic velocities, knots at the flow steps).')
    return text + (' Compensation profile: paper (125 ms rest-to-rest trapezoids, acceleration '
                   '10 x velocity).')


def _bone_motion(meta):
    model = meta.get('model', 'linear')
    if meta.get('bone_motion') == 'model':
        return ('Bone motion (moving cases): the SPMS plays the displacement the patient\'s '
                'identified %s model predicts from the ventilator\'s tidal volume, the paper\'s '
                'bench protocol (Algorithm 1: "SPMS and RSSSII do move"); the compensation uses '
                'the same model.' % model)
    if meta.get('bone_motion') == 'virtual_patient':
        return ('Bone motion (moving cases): the virtual patient, i.e. the virtual volunteer\'s '
                'true motion (lag behind the tidal volume, slow drift, small movements) driven by '
                'the ventilator; the compensation predicts it with the %s model identified from '
                'the volunteer\'s recording.' % model)
    return 'Prediction model: %s.' % model


def _quartiles(q, fmt='%.2f'):
    return (fmt + ' [' + fmt + ', ' + fmt + ']') % (q[1], q[0], q[2]) if q else '-'


def peak_force_section(summary):
    """Protocol peak_forces (paper Sec. V-D, Fig. 16): F_out and F_in per case, as the paper reads
    them (the recognizer's averaged force) and before the sensor (ground truth), and each moving
    case's median minus the stationary one beside the paper's."""
    lines = ['| case | rpm | trials | F_out median [IQR] [N] | F_in median [IQR] [N] | F_in defined '
             '| ground truth F_out / F_in [N] | F_out vs stationary | F_in vs stationary '
             '| paper (Sec. V-D) |', '|---|---|---|---|---|---|---|---|---|---|']
    for g in summary:
        base = next((b for b in summary if b['case'] == 'stationary' and b['rpm'] == g['rpm']),
                    None)
        diffs = ['-', '-']
        if base and g['case'] != 'stationary':
            for i, key in enumerate(('median_f_out_n', 'median_f_in_n')):
                if g[key] is not None and base[key]:
                    diffs[i] = '%+.2f N (%+.0f %%)' % (g[key] - base[key],
                                                       100.0 * (g[key] - base[key]) / base[key])
        paper = PAPER_PEAK_DIFFERENCES.get(g['case'])
        lines.append('| %s | %.0f | %d | %s | %s | %d | %s / %s | %s | %s | %s |' % (
            g['case'], g['rpm'], g['trials'], _quartiles(g['quartiles_f_out_n']),
            _quartiles(g['quartiles_f_in_n']), g['defined_f_in'], _num(g['median_f_out_truth_n']), _num(g['median_f_in_truth_n']),
            diffs[0], diffs[1],
            ('F_out %+.2f N, F_in %+.2f N' % paper) if paper and g['rpm'] == 12000.0 else '-'))
    return '\n'.join(lines)


def write_peak_force_report(summary, meta, figures, path, notes='', rows=None):
    lines = ['# Campaign report: peak forces', '',
             'Design: cases %s, spindle speeds %s rpm, %s trials per case and speed, base seed %s (%s seeds).'
             % (', '.join(meta['cases']), ', '.join('%.0f' % r for r in meta['rpms']),
                meta['trials'], meta['seed'], meta.get('seed_space', 'evaluation')),
             bone_motion_sentence(meta),
             'Simulator parameters: %s.' % (', '.join(
                 '%s = %s' % kv for kv in sorted((meta.get('simulator_params') or {}).items()))
                 or 'the defaults'),
             'Protocol peak_forces (paper Sec. V-D): the recognizer observes without stopping the '
             'drill, which goes through the inner cortical layer and is then stopped with '
             'retreat; successes are not defined. F_out and F_in are the peaks of the '
             'recognizer\'s averaged force (50-sample blocks, moving average of 10) before and '
             'after the deepest cut enters the inner cortical layer, up to the first stop, as the '
             'paper reads them off its force curves (Fig. 16); the ground-truth columns are the '
             'same peaks of the simulator\'s true thrust in 50-sample blocks, before the sensor '
             '(core engine).', '', '## Peak forces (Fig. 16)', '', peak_force_section(summary), '',
             '## Failure kinds', '', 'How each trial ended (src/pd_campaign/outcome.py). Under '
             'this protocol the drill is meant to go through: the protocol stops it once the tip '
             'is through, so a complete trial is breakthrough_before_stop; any other kind ended '
             'before the inner layer\'s end (a safety stop, or no stop).',
             '', '| case | rpm | trials | failure kinds |', '|---|---|---|---|']
    for g in summary:
        lines.append('| %s | %.0f | %d | %s |' % (g['case'], g['rpm'], g['trials'], ', '.join(
            '%s %d' % kv for kv in g['failure_kinds'].items())))
    lines.append('')
    lines += h1_section(rows)
    _write_with_notes_and_figures(lines, notes, figures, path)


def _write_with_notes_and_figures(lines, notes, figures, path):
    """Appends the notes and the figures to the report's lines and writes it atomically."""
    if notes:
        lines += [notes.strip(), '']
    if figures:
        lines += ['## Figures', '']
        for title, name in figures:
            lines += ['### %s' % title, '', '![%s](%s)' % (title, name), '']
    with atomic_write(path) as handle:
        handle.write('\n'.join(lines) + '\n')


FAILURE_KINDS_TEXT = (
    'Each trial\'s failure kind is the first that applies: breakthrough_before_stop / '
    'breakthrough_after_stop (the inner layer perforated before the first stop command, or with '
    'none, or after it: run-down, or the bone moving into the held drill), no_stop (never '
    'stopped, not perforated), safety_h1 / '
    'safety_h2 / safety_watchdog / safety_plausibility / safety_depth_limit / safety_other (the '
    'first stop was the monitor\'s position error, its force limit, a silent or broken stream, an '
    'implausible force, the plan\'s depth limit, another stop with retreat), stopped_before_inner, stopped_shallow (the recognizer stopped '
    'before the inner layer, or inside it with more than 2 mm left). Correct stops are the '
    'paper\'s successes; no penetration counts the trials without a breakthrough (Xia et al. 2024 '
    'report both). Quartiles (first / median / third): the stop\'s distance from the inner '
    'layer\'s end (inner cortex left below the cut at the first stop command), the overshoot '
    '(deepest cut at the end minus the depth of the layer\'s entry, the ideal stop point; only '
    'for trials that entered it) and the detection latency (entry into the inner layer to the '
    'first stop command; negative: entered only in the run-down after the stop). The H1 table '
    'counts every trial whose first stop was H1, whatever followed. Definitions: '
    'src/pd_campaign/outcome.py.')


def write_report_md(summary, meta, figures, path, notes='', faults=None, rows=None):
    if meta.get('protocol') == 'peak_forces':
        return write_peak_force_report(summary, meta, figures, path, notes, rows)
    lines = ['# Campaign report', '',
             'Design: cases %s, spindle speeds %s rpm, %s trials per case and speed, base seed %s (%s seeds).'
             % (', '.join(meta['cases']), ', '.join('%.0f' % r for r in meta['rpms']),
                '/'.join(str(n) for n in meta['trials']) if isinstance(meta['trials'], list)
                else meta['trials'], meta['seed'], meta.get('seed_space', 'evaluation')),
             'Simulator trial distribution: %s.' % (
                 'the defaults of config/simulator.yaml (the paper\'s conditions)'
                 if not meta.get('simulator') else
                 'config/simulator.yaml with the scenario\'s overrides ' + ', '.join(
                     '%s.%s = %g' % (group, key, value)
                     for group, values in sorted(meta['simulator'].items())
                     for key, value in sorted(values.items()))),
             bone_motion_sentence(meta),
             'Success: the recognizer stopped the drill inside the inner cortical layer (entered, '
             'not passed) with a residual thickness in (0, 2 mm] (paper Sec. V-C, V-E); the '
             'residual is the distance from the deepest cut to the far side of the inner '
             'cortical layer (simulator ground truth).', '',
             '## Results (Table III, Fig. 15, Fig. 16)', '', markdown_table(summary), '',
             '## Paper, 12000 rpm (Table III)', '',
             'Fisher\'s exact test, two-sided, of this campaign\'s 12000 rpm counts against the '
             'paper\'s (independent samples).', '',
             '| case | paper | this campaign | Fisher p |', '|---|---|---|---|']
    for case in meta['cases']:
        ours = [g for g in summary if g['case'] == case and g['rpm'] == 12000.0]
        paper = PAPER_TABLE_III.get(case)
        fisher = (stats.fisher_exact(ours[0]['successes'], ours[0]['trials'], paper[0], paper[1])
                  if ours and paper else None)
        lines.append('| %s | %s | %s | %s |' % (
            case, '%d/%d' % paper if paper else '-',
            '%d/%d' % (ours[0]['successes'], ours[0]['trials']) if ours else '-',
            '%.2g' % fisher if fisher is not None else '-'))
    fig15 = [(case, rpm, counts) for case, by_rpm in PAPER_FIG15_COUNTS.items()
             if case in meta['cases'] for rpm, counts in sorted(by_rpm.items())
             if rpm in [float(r) for r in meta['rpms']]]
    if fig15:
        lines += ['', '## Paper, success against spindle speed (Fig. 15)', '',
                  'Fisher\'s exact test, two-sided, of this campaign\'s counts against the paper\'s '
                  'compensated rates 90 / 50 / 40 %, read as 9/10, 5/10, 4/10 (the paper gives '
                  'rates only: 96 experiments over nine cells).', '',
                  '| case | rpm | paper | this campaign | Fisher p |', '|---|---|---|---|---|']
        for case, rpm, paper in fig15:
            ours = [g for g in summary if g['case'] == case and g['rpm'] == rpm and g['trials']]
            fisher = (stats.fisher_exact(ours[0]['successes'], ours[0]['trials'], *paper)
                      if ours else None)
            lines.append('| %s | %.0f | %d/%d | %s | %s |' % (
                case, rpm, paper[0], paper[1],
                '%d/%d' % (ours[0]['successes'], ours[0]['trials']) if ours else '-',
                '%.2g' % fisher if fisher is not None else '-'))
    lines += ['', '## Why trials failed', '',
              'Where the drill ended for every trial (simulator ground truth), and the tip-bone '
              'AP tracking of the failed trials (RMS about the feed line while drilling).', '',
              failure_table(summary), '',
              '## Failure kinds and the field\'s metrics', '',
              FAILURE_KINDS_TEXT, '', metrics_table(summary), '']
    if rows:
        lines += ['## Which line stopped the drill', '',
                  'The first stop of each trial: the recognizer (the primary stop), the planner\'s '
                  'plausibility bound on the recognizer\'s layers, the plan\'s depth limit, the '
                  'safety monitor, another stop (a silent component, the protocol) or none.', '',
                  stop_line_table(rows), '']
    lines += h1_section(rows)
    findings = analysis(summary)
    if findings:
        lines += [findings, '']
    if faults:
        lines += ['## Faults', '',
                  'Each fault injected once per trial, when the deepest cut first reaches a depth '
                  'drawn from the seed between the bone surface and the inner cortical layer '
                  '(breathing faults from the next breath, command faults on the next command); '
                  'every fault on the same seeds as the fault-free row. Fault sizes: %s.' % (
                      ', '.join('%s = %g' % kv for kv in sorted(
                          (meta.get('fault_params') or {}).items())) or 'the defaults'),
                  'Stop delay: fault to the first stop command (recognizer or monitor); retreat '
                  'delay: fault to the start of the retreat; residual: inner cortical thickness '
                  'left at the end of the trial (negative: broken through).', '',
                  fault_table(faults), '']
    _write_with_notes_and_figures(lines, notes, figures, path)
