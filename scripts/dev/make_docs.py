#!/usr/bin/python3
"""The documents' generated blocks, from the archived results in doc/results/.

A generated number in a sentence is `<!-- n: SPEC -->TEXT<!-- /n -->` (doc_numbers.py); the
figures of FIGURES in doc/images/ are drawn from the archive too.
A generated block is the text between `<!-- generated: NAME -->` and `<!-- end generated -->` in
a document; NAME is one of BLOCKS, a function of the archive folder that returns the block's
markdown (the dataset's column tables come from pd_campaign.dataset's declaration instead).
`make docs` rewrites every block from the archive (run on a checkout it leaves `git diff` empty);
`--check` rewrites nothing and exits 1 naming every block that differs (test_generated_docs.py).
`--archive RESULTS_DIR` first copies what the blocks read from a `make run` output (default
results/) into doc/results/: the trial tables trimmed to the columns the tables use, the
campaigns' summary.json, Table II, the robustness curves' csv, the leaderboard's json and the
sensitivity sweeps' csv and conclusions.

usage: make_docs.py [--check] [--archive [RESULTS_DIR]]"""
import argparse
import csv
import functools
import glob
import io
import json
import os
import re
import shutil
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, '..', '..'))
sys.path.insert(0, os.path.join(ROOT, 'src'))
sys.path.insert(0, HERE)

from pd_campaign import compare, dataset, leaderboard, plots, report, stats, trials_csv  # noqa: E402
from pd_campaign.atomic import atomic_path  # noqa: E402
import adaptive_tables  # noqa: E402
import campaign_results_tables  # noqa: E402
import depth_limit_tables  # noqa: E402
import latency_table  # noqa: E402
import doc_numbers  # noqa: E402
import equivalence_tables  # noqa: E402
import population_tables  # noqa: E402
import results_tables  # noqa: E402
import sensitivity_tables  # noqa: E402

ARCHIVE = os.path.join(ROOT, 'doc', 'results')
# Every document that may hold a generated block: the README and the pages of doc/ (the blocks
# are today in doc/results.md, doc/identification.md and doc/dataset.md).
DOCUMENTS = tuple(['README.md'] + sorted(
    os.path.relpath(path, ROOT) for path in glob.glob(os.path.join(ROOT, 'doc', '*.md'))))
BLOCK = re.compile(r'(<!-- generated: ([a-z_]+) -->\n)(.*?)(<!-- end generated -->)', re.S)
# The trial columns the generated tables read (trials_csv.normalise_row needs the first five;
# aggregate.stop_line the stop's source and reason). The reason is archived as its kind, the
# text before its first colon ("depth_limit", "implausible force", "inner cortical layer
# reached"), which is what stop_line reads of it. The volunteer, the inner layer's thickness,
# the contact losses and the H1 error are what the generated numbers of campaign_results.md
# read, the lockstep's timeouts what its ROS agreement table reads.
COLUMNS = ('trial_id', 'case', 'rpm', 'index', 'seed', 'success', 'breakthrough', 'failure_kind',
           'tracking_rms_mm', 'residual_mm', 'max_depth_mm', 'inner_start_mm',
           'model_ap_slope_mm_per_ml', 'identification_r2_ap', 'patient_ap_slope_mm_per_ml',
           'fault', 'stop_source', 'stop_reason', 'volunteer_id', 'inner_cortical_mm',
           'contact_loss_count', 'h1_error_mm', 'lockstep_timeouts', 'error')
# The campaigns of a `make run` output the blocks read, and what of each: 'summary' (every row
# and summary.json: the paper's design on the three benches), 'summary_only' (summary.json: the
# fault campaign's per-fault table), 'rows' (every row) or 'compensated' (the compensated
# 12000 rpm rows). A name ending in /* is every campaign folder
# inside that folder (one per class pair).
CAMPAIGNS = {
    'campaign': 'summary', 'campaign_exact': 'summary', 'campaign_virtual_patient': 'summary',
    'campaign_hysteresis': 'summary', 'campaign_peak_forces': 'summary',
    'campaign_adaptive': 'compensated',
    'campaign_adaptive_ros': 'compensated',
    'adaptive_amplitude': 'compensated', 'adaptive_amplitude_paper': 'compensated',
    'campaign_realistic': 'summary', 'campaign_realistic_adaptive': 'compensated',
    'campaign_population': 'summary', 'campaign_population_adaptive': 'compensated',
    'campaign_sensor_1khz': 'summary', 'campaign_faults': 'summary_only',
    'campaign_depth_limit': 'rows', 'depth_limit_faults/*': 'rows',
    'depth_limit_amplitude/*': 'rows', 'depth_limit_amplitude_without_plan': 'rows',
    'uncompensated_row/*': 'summary',
    'campaign_ros': 'rows', 'campaign_ros_repeat': 'rows', 'campaign_realistic_ros': 'rows',
    'baseline_tracked_marker': 'summary', 'baseline_force_difference': 'summary',
}
# Measurements of the developer scripts outside `make run`, in the same results folder when they
# ran (run_latency_budget.sh writes results/latency_budget/): archived by --archive when present,
# kept as archived otherwise.
OPTIONAL_CAMPAIGNS = {'latency_budget/*': 'rows'}
# Files of a `make run` output archived as they are: the robustness curves and the leaderboard.
WHOLE_FILES = (os.path.join('robustness', 'robustness.csv'),
               os.path.join('leaderboard', 'leaderboard.json'))


def captured(function, *args):
    """What `function(*args)` prints."""
    saved, sys.stdout = sys.stdout, io.StringIO()
    try:
        function(*args)
        return sys.stdout.getvalue()
    finally:
        sys.stdout = saved


def robustness_table(archive):
    """doc/results.md's digest of the robustness curves: per error, each compensator's success at
    the two ends and at the nominal point, and the range where the adaptive one holds 95 %."""
    with open(os.path.join(archive, 'robustness', 'robustness.csv')) as handle:
        rows = list(csv.DictReader(handle))
    lines = ['| error | compensator | success at the smallest / nominal / largest size (of '
             'trials) | H1 stops at the ends | sizes at or above 95 % |', '|---|---|---|---|---|']
    for error in dict.fromkeys(r['error'] for r in rows):
        for compensator in dict.fromkeys(r['compensator'] for r in rows):
            points = sorted((r for r in rows if r['error'] == error
                             and r['compensator'] == compensator), key=lambda r: float(r['value']))
            nominal = next(r for r in points if r['nominal'] == 'true')
            held = [r['value'] for r in points if int(r['successes']) >= 0.95 * int(r['trials'])]
            unit = points[0]['unit']
            lines.append('| %s | %s | %s / %s / %s of %s | %s, %s | %s |' % (
                '%s [%s]' % (error, unit) if unit else '%s (factor)' % error,
                compensator.split('/')[-1], points[0]['successes'],
                nominal['successes'], points[-1]['successes'], nominal['trials'],
                points[0]['h1_stops'], points[-1]['h1_stops'],
                ', '.join(held) if held else 'none'))
    return '\n'.join(lines) + '\n'


def population_block(archive):
    trials = population_tables.rows(os.path.join(archive, 'campaign_population'))
    summary = results_tables.load(os.path.join(archive, 'campaign_population'))
    return (captured(results_tables.design_table, summary) + '\n'
            + captured(population_tables.kinds_table, summary, trials))


def paper_design(archive):
    """The README's table: the paper's design on the paper's bench against Table III."""
    summary = results_tables.load(os.path.join(archive, 'campaign'))
    return captured(results_tables.design_table, summary)


def paper_metrics(archive):
    """doc/results.md's table: why the paper's bench's trials ended as they did."""
    summary = results_tables.load(os.path.join(archive, 'campaign'))
    return captured(results_tables.metrics_table, summary)


@functools.lru_cache(maxsize=None)
def equivalence_block(archive):
    """doc/results.md's non-inferiority table and its conclusion (computed once per archive)."""
    return captured(equivalence_tables.main, ['', archive])


def equivalence_summary(archive):
    """The README's sentence: the conclusion of the non-inferiority table."""
    return equivalence_block(archive).strip().splitlines()[-1] + '\n'


def rows_at_12000(archive, name):
    """The archived campaign `name`'s 12000 rpm trials."""
    return [r for r in trials_csv.read_trials_csv(os.path.join(archive, name, 'trials.csv'))
            if r['rpm'] == 12000.0]


def sensor_rate_block(archive):
    """doc/experiments.md's table: the paper's bench with a 1 kHz F/T sensor against the 333 Hz
    one (the paper campaign's 12000 rpm trials), paired seed for seed."""
    lines = ['| case (12000 rpm) | 1 kHz | 333 Hz | both / only 1 kHz / only 333 Hz / neither | '
             'McNemar p | 1 kHz - 333 Hz [95 %] |', '|---|---|---|---|---|---|']
    for g in compare.compare(rows_at_12000(archive, 'campaign_sensor_1khz'),
                             rows_at_12000(archive, 'campaign')):
        low, high = g['difference_ci95']
        lines.append('| %s | %d/%d | %d/%d | %d / %d / %d / %d | %.3g | %+.1f points [%+.1f, %+.1f] |'
                     % (g['case'], g['successes_a'], g['pairs'], g['successes_b'], g['pairs'],
                        g['both'], g['only_a'], g['only_b'], g['neither'], g['mcnemar_p'],
                        100 * g['difference'], 100 * low, 100 * high))
    return '\n'.join(lines) + '\n'


def setting_changed(meta):
    """What a variant of the uncompensated row changed, from its summary's meta."""
    names = {'pre_average_s': 'window %s s', 'ventilator/tv_max_ml': 'tidal volume %g ml',
             'force_sensor_rate_hz': 'sensor %g Hz'}
    changed = dict(meta.get('simulator_params') or {}, **(meta.get('recognizer_params') or {}))
    return ', '.join(names.get(k, k + ' %s') % (v,) for k, v in sorted(changed.items()))


def outcome_counts(rows):
    """Successes, breakthroughs and stops before the inner layer among `rows`."""
    return (sum(r['success'] for r in rows), sum(r['breakthrough'] for r in rows),
            sum(r['failure_kind'] == 'stopped_before_inner' for r in rows))


def uncompensated_row_block(archive):
    """doc/results.md's table: the paper's bench's 12000 rpm trials with one setting changed,
    paired seed for seed with the paper campaign's."""
    paper = rows_at_12000(archive, 'campaign')
    lines = ['| variant | case | successes | breakthroughs | stopped before the inner layer | '
             'paper\'s bench, same seeds: successes | only the variant / only the paper\'s | '
             'McNemar p | Table III | Fisher p vs Table III |',
             '|---|---|---|---|---|---|---|---|---|---|']
    base = [r for r in paper if r['case'] == 'uncompensated']
    successes, breakthroughs, early = outcome_counts(base)
    row = report.PAPER_TABLE_III['uncompensated']
    lines.append('| none (the paper\'s bench) | uncompensated | %d/%d | %d | %d | - | - | - | %d/%d | '
                 '%.2g |' % (successes, len(base), breakthroughs, early, row[0], row[1],
                             stats.fisher_exact(successes, len(base), *row)))
    for folder in sorted(glob.glob(os.path.join(archive, 'uncompensated_row', '*', ''))):
        name = os.path.basename(os.path.dirname(folder))
        variant = rows_at_12000(archive, os.path.join('uncompensated_row', name))
        changed = setting_changed(results_tables.load(folder)['meta'])
        for g in compare.compare(variant, paper):
            _, breakthroughs, early = outcome_counts(
                [r for r in variant if r['case'] == g['case']])
            paper_row = report.PAPER_TABLE_III[g['case']]
            lines.append('| %s | %s | %d/%d | %d | %d | %d/%d | %d / %d | %.2g | %d/%d | %.2g |' % (
                changed, g['case'], g['successes_a'], g['pairs'], breakthroughs, early,
                g['successes_b'], g['pairs'], g['only_a'], g['only_b'], g['mcnemar_p'],
                paper_row[0], paper_row[1],
                stats.fisher_exact(g['successes_a'], g['pairs'], *paper_row)))
    return '\n'.join(lines) + '\n'


def latency_block(archive):
    """doc/campaign_results.md's latency budget: latency_table.py over the archived core-engine
    cells (run_latency_budget.sh's <delay>_<seconds> folders), the 1 ms command delay (the
    defaults) first, then by delay and value."""
    base = os.path.join(archive, 'latency_budget')
    cells = []
    for folder in os.listdir(base):
        if folder.startswith('ros_'):
            continue  # the ROS pipeline's cells (ros_agreement.md), not in the table
        name, _, value = folder.rpartition('_')
        cells.append((folder != 'command_to_arm_s_0.001', name, float(value),
                      '%s = %s s=%s' % (name, value, os.path.join(base, folder))))
    return captured(latency_table.main, [cell[-1] for cell in sorted(cells)])


def leaderboard_block(archive):
    """doc/leaderboard.md's board: the archived leaderboard.json rendered as campaign_leaderboard
    renders it (the shipped config/leaderboard.yaml's entries, the archived stamp), without its
    title."""
    with open(os.path.join(archive, 'leaderboard', 'leaderboard.json')) as handle:
        data = json.load(handle)
    config = leaderboard.load_config(leaderboard.DEFAULT_CONFIG)
    args = argparse.Namespace(trials=data['trials'], cases=config.get('cases'), extras={
        bench: {'ranks': data['ranks'][bench], 'strata': data['strata'][bench],
                'hidden': data['hidden'][bench]['board'],
                'hidden_specimens': data['hidden'][bench]['specimens']}
        for bench in data['ranks']})
    text = leaderboard.markdown(data['boards'], data['tuning'], config, data['meta'], args,
                                marks=data['stamp'])
    return text.split('\n', 2)[2].rstrip('\n') + '\n'


BLOCKS = {
    'adaptive': lambda archive: captured(adaptive_tables.main, ['', archive]),
    'equivalence': equivalence_block,
    'equivalence_summary': equivalence_summary,
    'paper_design': paper_design,
    'paper_metrics': paper_metrics,
    'population': population_block,
    'three_benches': lambda archive: captured(population_tables.benches_table, archive),
    'population_identification': lambda archive: captured(
        population_tables.identification_table,
        population_tables.rows(os.path.join(archive, 'campaign_population')),
        os.path.join(archive, 'campaign', 'table2.csv')),
    'robustness': robustness_table,
    'sensor_rate': sensor_rate_block,
    'fault_campaign': lambda archive: report.fault_table(
        results_tables.load(os.path.join(archive, 'campaign_faults'))['faults']) + '\n',
    'uncompensated_row': uncompensated_row_block,
    'leaderboard': leaderboard_block,
    'latency_budget': latency_block,
    'depth_limit_design': lambda archive: captured(depth_limit_tables.design_table, archive),
    'depth_limit_faults': lambda archive: captured(depth_limit_tables.faults_table, archive),
    'depth_limit_classes': lambda archive: captured(depth_limit_tables.amplitude_table, archive),
    'depth_limit_control': lambda archive: captured(depth_limit_tables.control_table, archive),
    # doc/campaign_results.md's tables (campaign_results_tables.py).
    'profiles': campaign_results_tables.profiles_table,
    'profile_pairs': campaign_results_tables.profile_pairs_table,
    'benches': campaign_results_tables.benches_table,
    'imperfections': campaign_results_tables.imperfections_table,
    'engine_agreement': campaign_results_tables.agreement_table,
    'baselines': campaign_results_tables.baselines_table,
    'sensitivity_paper': lambda archive: sensitivity_tables.screen_table(archive,
                                                                          'sensitivity_paper'),
    'sensitivity_paper_conclusions': lambda archive: sensitivity_tables.conclusions_table(
        archive, 'sensitivity_paper'),
    'sensitivity_realistic': lambda archive: sensitivity_tables.screen_table(
        archive, 'sensitivity_realistic'),
    'sensitivity_realistic_conclusions': lambda archive: sensitivity_tables.conclusions_table(
        archive, 'sensitivity_realistic'),
    'sensitivity_speed': sensitivity_tables.speed_table,
    'sensitivity_speed_conclusions': lambda archive: sensitivity_tables.conclusions_table(
        archive, 'sensitivity_speed'),
    # doc/dataset.md's column tables: from the dataset's declaration, not the archive.
    'dataset_columns': lambda archive: dataset.columns_markdown(),
}


# The documents' figures drawn from the archive (doc/images/NAME: a function of the archive
# folder and an output folder that writes the figure there and returns its file name).
def leaderboard_figure(archive, out_dir):
    """The leaderboard's figure from its archived boards and the shipped entries."""
    with open(os.path.join(archive, 'leaderboard', 'leaderboard.json')) as handle:
        boards = json.load(handle)['boards']
    config = leaderboard.load_config(leaderboard.DEFAULT_CONFIG)
    leaderboard.figure(boards, config, os.path.join(out_dir, 'leaderboard.png'))
    return 'leaderboard.png'


FIGURES = {
    'campaign_fig15.png': lambda archive, out_dir: plots.fig15(
        results_tables.load(os.path.join(archive, 'campaign'))['groups'], out_dir),
    'leaderboard.png': leaderboard_figure,
}


def stale_figures(archive, write):
    """The figures of FIGURES whose file in doc/images differs from what the archive draws
    (matplotlib's Agg output is the same bytes for the same data); with `write`, replaced."""
    stale = []
    with tempfile.TemporaryDirectory() as out_dir:
        for name, draw in FIGURES.items():
            drawn = os.path.join(out_dir, draw(archive, out_dir))
            target = os.path.join(ROOT, 'doc', 'images', name)
            with open(drawn, 'rb') as new:
                fresh = new.read()
            if os.path.isfile(target):
                with open(target, 'rb') as old:
                    if old.read() == fresh:
                        continue
            stale.append('doc/images/' + name)
            if write:
                with atomic_path(target) as tmp:
                    shutil.copyfile(drawn, tmp)
    return stale


def campaign_folders(results, campaigns=None):
    """(folder relative to `results`, what to keep) for every campaign of `campaigns` (default
    CAMPAIGNS) found there; a pattern's folders are those holding a trials.csv."""
    folders = []
    for name, keep in (CAMPAIGNS if campaigns is None else campaigns).items():
        if name.endswith('/*'):
            base = os.path.join(results, name[:-2])
            inner = sorted(d for d in os.listdir(base)) if os.path.isdir(base) else []
            folders += [(os.path.join(name[:-2], d), keep) for d in inner
                        if os.path.isfile(os.path.join(base, d, 'trials.csv'))]
            if not inner:
                folders.append((name[:-2], keep))  # reported missing below
        else:
            folders.append((name, keep))
    return folders


def archive_results(results):
    """Copies what the blocks read from a `make run` output into doc/results/; nothing when a
    file is missing (SystemExit naming it)."""
    folders = campaign_folders(results)
    needed = [os.path.join(name, 'trials.csv') for name, keep in folders
              if keep != 'summary_only'] + [
        os.path.join(name, 'summary.json') for name, keep in folders
        if keep in ('summary', 'summary_only')] + [
        os.path.join('campaign', 'table2.csv')] + list(WHOLE_FILES) + [
        os.path.join(sweep, 'sensitivity.csv') for sweep in sensitivity_tables.SWEEPS]
    missing = [path for path in needed if not os.path.isfile(os.path.join(results, path))]
    if missing:
        sys.exit('make_docs: --archive %s: not a complete make run output, missing %s'
                 % (results, ', '.join(missing)))
    for name, keep in folders + [(name, keep) for name, keep in
                                 campaign_folders(results, OPTIONAL_CAMPAIGNS)
                                 if os.path.isfile(os.path.join(results, name, 'trials.csv'))]:
        archive_campaign(os.path.join(results, name), os.path.join(ARCHIVE, name), keep)
    for sweep in sensitivity_tables.SWEEPS:
        sensitivity_tables.archive_sweep(os.path.join(results, sweep),
                                         os.path.join(ARCHIVE, sweep))
    for path in WHOLE_FILES:
        os.makedirs(os.path.dirname(os.path.join(ARCHIVE, path)), exist_ok=True)
        with atomic_path(os.path.join(ARCHIVE, path)) as tmp:
            shutil.copyfile(os.path.join(results, path), tmp)


def archive_campaign(source, target, keep):
    """One campaign's trial table, trimmed to the COLUMNS it has (and to its compensated
    12000 rpm rows for 'compensated'), with its summary.json for 'summary' and 'summary_only'
    (then alone) and Table II for the paper's campaign."""
    os.makedirs(target, exist_ok=True)
    if keep == 'summary_only':
        with atomic_path(os.path.join(target, 'summary.json')) as tmp:
            shutil.copyfile(os.path.join(source, 'summary.json'), tmp)
        return
    with open(os.path.join(source, 'trials.csv')) as handle:
        reader = csv.DictReader(handle)
        rows = [r for r in reader if keep != 'compensated' or (
            r['case'] == 'compensated' and float(r['rpm']) == 12000.0)]
        columns = [c for c in COLUMNS if c in reader.fieldnames]
    for row in rows:
        if row.get('stop_reason'):
            row['stop_reason'] = row['stop_reason'].split(':')[0]
    with atomic_path(os.path.join(target, 'trials.csv')) as tmp, open(tmp, 'w') as out:
        writer = csv.DictWriter(out, fieldnames=columns, extrasaction='ignore',
                                lineterminator='\n')
        writer.writeheader()
        writer.writerows(rows)
    files = (['summary.json'] if keep == 'summary' else []) + (
        ['table2.csv'] if os.path.basename(source) == 'campaign' else [])
    for file_name in files:
        with atomic_path(os.path.join(target, file_name)) as tmp:
            shutil.copyfile(os.path.join(source, file_name), tmp)


def regenerate(text, archive):
    """The document `text` with every generated block and number (doc_numbers.py) rebuilt; and
    the names of the blocks."""
    names = []

    def rebuilt(match):
        name = match.group(2)
        if name not in BLOCKS:
            raise KeyError('unknown generated block %r (known: %s)' % (name, ', '.join(BLOCKS)))
        names.append(name)
        return match.group(1) + BLOCKS[name](archive) + match.group(4)
    return doc_numbers.regenerate(BLOCK.sub(rebuilt, text), archive)[0], names


def stale_parts(document, text, new):
    """What of `document` differs between its `text` and the `new` one: 'document: block' for a
    block, 'document: n: SPEC (TEXT, archive NEW)' for a number."""
    old_blocks = dict((m.group(2), m.group(3)) for m in BLOCK.finditer(text))
    new_blocks = dict((m.group(2), m.group(3)) for m in BLOCK.finditer(new))
    stale = ['%s: %s' % (document, n) for n in new_blocks if old_blocks[n] != new_blocks[n]]
    numbers = zip(doc_numbers.NUMBER.finditer(text), doc_numbers.NUMBER.finditer(new))
    return stale + ['%s: n: %s (%s, archive %s)' % (document, old.group(2), old.group(3),
                                                    fresh.group(3))
                    for old, fresh in numbers if old.group(3) != fresh.group(3)]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--check', action='store_true',
                        help='change nothing; exit 1 naming every block that differs')
    parser.add_argument('--archive', nargs='?', const=os.path.join(ROOT, 'results'),
                        metavar='RESULTS_DIR', help='first copy a make run output into doc/results/')
    args = parser.parse_args(argv)
    if args.archive:
        archive_results(args.archive)
    stale = []
    for document in DOCUMENTS:
        path = os.path.join(ROOT, document)
        with open(path) as handle:
            text = handle.read()
        new, _ = regenerate(text, ARCHIVE)
        if new == text:
            continue
        if args.check:
            stale += stale_parts(document, text, new)
        else:
            with atomic_path(path) as tmp, open(tmp, 'w') as out:
                out.write(new)
    stale += stale_figures(ARCHIVE, write=not args.check)
    if stale and args.check:
        sys.stderr.write('make_docs: blocks, numbers and figures that differ from doc/results/ (make docs): %s\n'
                         % ', '.join(stale))
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
