"""The leaderboard's statistics beyond the per-cell counts (doc/leaderboard.md): bootstrapped rank
intervals over specimens, results by stratum (bone density, inner-cortex thickness, spindle
speed) and the hidden-condition board, with their Markdown.

A specimen is a trial seed at a speed: the campaign's seeds depend on (seed space, base seed,
speed, index) only, so every case and every entry drills the same specimen under the same seed,
and a resample of specimens is paired across entries and cases."""
import numpy as np

from . import dataset, design, stats

RESAMPLES = 1000
SEED = 20260
LEVEL = 0.95
STRATA = ('bone density', 'inner cortex thickness', 'speed')


def _ok(row):
    return not row.get('error')


def specimen_key(row):
    return (float(row['rpm']), int(row['seed']))


def success_matrix(rows_by_entry, case=None):
    """(entries, specimens, successes[entry, specimen]): each entry's correct stops per specimen
    (summed over the cases, or in `case` only); an errored trial counts as a failure."""
    entries = list(rows_by_entry)
    specimens = sorted({specimen_key(r) for rows in rows_by_entry.values() for r in rows
                        if case is None or r['case'] == case})
    column = {key: k for k, key in enumerate(specimens)}
    matrix = np.zeros((len(entries), len(specimens)))
    for e, name in enumerate(entries):
        for r in rows_by_entry[name]:
            if (case is None or r['case'] == case) and _ok(r) and r.get('success'):
                matrix[e, column[specimen_key(r)]] += 1
    return entries, specimens, matrix


def ranks_of(totals):
    """Competition ranks, 1 the best: 1 + the number of entries with strictly more successes
    (tied entries share the better rank). `totals`: [entries] or [resamples, entries]."""
    totals = np.asarray(totals, float)
    return 1 + (totals[..., None, :] > totals[..., :, None]).sum(axis=-1)


def bootstrap_ranks(matrix, resamples=RESAMPLES, seed=SEED, level=LEVEL):
    """Per entry (row of `matrix`, successes per specimen): its rank on all specimens and the
    percentile interval (`level`) of its rank over `resamples` resamples of the specimens with
    replacement, the same resample for every entry (paired), seeded. [(rank, low, high)]."""
    matrix = np.asarray(matrix, float)
    count = matrix.shape[1]
    if count == 0:
        return [(1, 1, 1)] * matrix.shape[0]
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, count, size=(resamples, count))
    weights = np.zeros((resamples, count))
    np.add.at(weights, (np.arange(resamples)[:, None], picks), 1.0)
    ranks = ranks_of(weights @ matrix.T)  # [resamples, entries]
    alpha = (1.0 - level) / 2.0
    low = np.quantile(ranks, alpha, axis=0, method='inverted_cdf')
    high = np.quantile(ranks, 1.0 - alpha, axis=0, method='inverted_cdf')
    point = ranks_of(matrix.sum(axis=1))
    return [(int(p), int(a), int(b)) for p, a, b in zip(point, low, high)]


def rank_table(rows_by_entry, cases, resamples=RESAMPLES, seed=SEED):
    """{entry: {'all': {...}, case: {...}}}, each {rank, interval, correct, trials,
    specimens}: the ranks pooled over the cases (a specimen with all its cases) and per case."""
    out = {name: {} for name in rows_by_entry}
    for case in [None] + list(cases):
        entries, specimens, matrix = success_matrix(rows_by_entry, case)
        for name, (rank, low, high), row in zip(entries, bootstrap_ranks(
                matrix, resamples, seed), matrix):
            trials = sum(1 for r in rows_by_entry[name] if case is None or r['case'] == case)
            out[name][case or 'all'] = {'rank': rank, 'interval': [low, high],
                                        'correct': int(row.sum()), 'trials': trials,
                                        'specimens': len(specimens)}
    return out


def tertile_edges(values):
    """The two edges that cut `values` into three groups of about equal size (None when there
    are fewer than three values)."""
    values = [v for v in values if v is not None and np.isfinite(v)]
    if len(values) < 3:
        return None
    return [float(v) for v in np.quantile(values, [1.0 / 3.0, 2.0 / 3.0])]


def stratum_edges(train_npz, references=None):
    """The strata's edges, from the training split's trial table (never the test split's):
    the tertiles of its specimens' density ratios (over `references`, the dataset's
    [[rpm, N]]; default the training specimens' own medians) and inner-cortex thicknesses;
    and the references under 'references'."""
    with np.load(train_npz) as z:
        rows = [{'rpm': rpm, 'seed': int(seed), 'case': case, 'f_out_truth_n': f,
                 'inner_cortical_mm': thick}
                for rpm, seed, case, f, thick in zip(
                    z['trial_rpm'], z['trial_seed'], z['trial_case'], z['trial_f_out_truth_n'],
                    z['trial_inner_cortical_mm'])]
    thickness = {specimen_key(r): float(r['inner_cortical_mm']) for r in rows}
    references = references or dataset.density_references(dataset.specimen_peaks(rows))
    return {'bone density': tertile_edges(list(dataset.specimen_densities(
                rows, references).values())),
            'inner cortex thickness': tertile_edges(list(thickness.values())),
            'references': references}


def _band(value, edges, unit, pattern):
    if value is None or edges is None:
        return None
    names = ('low', 'middle', 'high')
    k = int(np.searchsorted(edges, value, side='right'))
    bounds = ['< ' + pattern % edges[0], pattern % edges[0] + '-' + pattern % edges[1],
              '>= ' + pattern % edges[1]]
    return '%d %s (%s%s)' % (k + 1, names[k], bounds[k], unit)


def strata_of(rows_by_entry, edges):
    """{specimen: {stratum: label}}: each specimen's bone-density band (its density ratio,
    dataset.specimen_densities over every entry's trials), inner-cortex thickness band and
    speed; bands cut at `edges` (stratum_edges)."""
    every = [r for rows in rows_by_entry.values() for r in rows if _ok(r)]
    densities = dataset.specimen_densities(every, edges.get('references'))
    thickness = {specimen_key(r): r.get('inner_cortical_mm') for r in every}
    out = {}
    for key in {specimen_key(r) for r in every}:
        out[key] = {
            'bone density': _band(densities.get(key), edges.get('bone density'),
                                  ' x the reference', '%.3f'),
            'inner cortex thickness': _band(thickness.get(key),
                                            edges.get('inner cortex thickness'), ' mm', '%.2f'),
            'speed': '%d rpm' % key[0]}
    return out


def _cell(rows):
    n = sum(1 for r in rows if _ok(r))
    k = sum(1 for r in rows if _ok(r) and r.get('success'))
    low, high = stats.wilson_interval(k, n)
    return {'correct': k, 'n': n, 'wilson95': [low, high]}


def strata_table(rows_by_entry, edges):
    """[{stratum, band, entry, correct, n, wilson95}]: each entry's correct stops per band of
    each stratum, the cases pooled."""
    labels = strata_of(rows_by_entry, edges)
    out = []
    for stratum in STRATA:
        bands = sorted({v[stratum] for v in labels.values() if v[stratum]})
        for band in bands:
            for name, rows in rows_by_entry.items():
                mine = [r for r in rows if labels.get(specimen_key(r), {}).get(stratum) == band]
                out.append(dict(_cell(mine), stratum=stratum, band=band, entry=name))
    return out


def hidden_board(rows_by_entry, rule):
    """[{entry, case, hidden: cell, seen: cell}] and {specimen: reason}: each entry's correct
    stops per case on the specimens under the dataset's hidden conditions (`rule`, split.json's
    meta.hidden_conditions: the conditions its training and validation splits never hold) and
    on the others. None when the dataset declares no rule (an older dataset)."""
    if not rule:
        return None, {}
    every = [r for rows in rows_by_entry.values() for r in rows if _ok(r)]
    densities = dataset.specimen_densities(every, rule.get('density_reference_n'))
    low, high = rule['seen_density_range']
    reasons = {}
    for r in every:
        key = specimen_key(r)
        why = []
        if int(r.get('volunteer_id') or -1) in rule['volunteers']:
            why.append('breathing of volunteer %d' % int(r['volunteer_id']))
        if key in densities and not low <= densities[key] <= high:
            why.append('density %.3f x the reference' % densities[key])
        if why:
            reasons[key] = '; '.join(why)
    cases = [c for c in design.CASES if any(r['case'] == c for r in every)]
    out = []
    for name, rows in rows_by_entry.items():
        for case in cases:
            mine = [r for r in rows if r['case'] == case]
            out.append({'entry': name, 'case': case,
                        'hidden': _cell([r for r in mine if specimen_key(r) in reasons]),
                        'seen': _cell([r for r in mine if specimen_key(r) not in reasons])})
    return out, reasons


def _count(cell):
    if not cell['n']:
        return '-'
    return '%d/%d (%.0f-%.0f %%)' % (cell['correct'], cell['n'], 100 * cell['wilson95'][0],
                                     100 * cell['wilson95'][1])


def ranks_markdown(ranks, cases):
    lines = ['| entry | correct stops, all cases | rank (95 % interval) | ' + ' | '.join(
        '%s: rank (95 %% interval)' % c for c in cases) + ' |',
        '|---|---|---|' + '---|' * len(cases)]
    order = sorted(ranks, key=lambda name: (ranks[name]['all']['rank'], name))
    for name in order:
        cells = [ranks[name][k] for k in ['all'] + list(cases)]
        lines.append('| %s | %d/%d | %s |' % (
            name, cells[0]['correct'], cells[0]['trials'], ' | '.join(
                '%d (%d-%d)' % (c['rank'], c['interval'][0], c['interval'][1]) for c in cells)))
    return lines


def strata_markdown(table):
    entries = list(dict.fromkeys(r['entry'] for r in table))
    lines = ['| stratum | band | ' + ' | '.join(entries) + ' |',
             '|---|---|' + '---|' * len(entries)]
    bands = list(dict.fromkeys((r['stratum'], r['band']) for r in table))
    for stratum, band in bands:
        cells = {r['entry']: r for r in table if (r['stratum'], r['band']) == (stratum, band)}
        lines.append('| %s | %s | %s |' % (stratum, band, ' | '.join(
            _count(cells[e]) for e in entries)))
    return lines


def hidden_markdown(board, reasons):
    if board is None:
        return ['The dataset declares no hidden conditions (made before they existed): no '
                'hidden-condition board.']
    specimens = len(reasons)
    lines = ['%d specimen(s) of these trials lie under a hidden condition (%s).' % (
        specimens, '; '.join(sorted(set(reasons.values()))) or 'none'), '',
             '| entry | case | hidden conditions: correct stops (95 % CI) | seen conditions |',
             '|---|---|---|---|']
    for r in board:
        lines.append('| %s | %s | %s | %s |' % (r['entry'], r['case'], _count(r['hidden']),
                                                _count(r['seen'])))
    return lines
