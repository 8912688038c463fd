"""The sweep's table (success at each end of each constant against the nominal bench, paired
trial by trial) and the verdicts of the paper's conclusions at every bench."""
from .. import stats
from .sweep import ALPHA, BEST_RPM, ENDS, SPEED_CASE, bench_id, same_value

# --- the table ---------------------------------------------------------------------------------

def _group(rows, case, rpm):
    return [r for r in rows if r['case'] == case and r['rpm'] == rpm]


def success_cell(rows):
    """Successes of the trials that did not error, their count, the Wilson 95 % interval, the
    errored trials and the failure kinds (pd_campaign.outcome) by count."""
    valid = [r for r in rows if not r.get('error')]
    successes = sum(1 for r in valid if r['success'])
    kinds = {}
    for row in valid:
        kind = row.get('failure_kind') or ('success' if row['success'] else 'unknown')
        kinds[kind] = kinds.get(kind, 0) + 1
    return {'successes': successes, 'trials': len(valid), 'errors': len(rows) - len(valid),
            'wilson95': list(stats.wilson_interval(successes, len(valid))),
            'failure_kinds': dict(sorted(kinds.items()))}


def rate(cell):
    """Success rate of a cell, None without trials."""
    return cell['successes'] / cell['trials'] if cell['trials'] else None


def paired_test(end_rows, nominal_rows):
    """McNemar's exact test of an end against the nominal bench on the same seeds."""
    pairs, _, only_end, only_nominal, _ = stats.paired_counts(end_rows, nominal_rows,
                                                             key=lambda r: r['seed'])
    return {'pairs': pairs, 'only_end': only_end, 'only_nominal': only_nominal,
            'mcnemar_p': stats.mcnemar_exact(only_end, only_nominal)}


def moved_kinds(end_cell, nominal_cell):
    """{failure kind: [count at the nominal, count at the end]} of the kinds whose count moved
    (success left out: the success columns give it)."""
    a, b = nominal_cell['failure_kinds'], end_cell['failure_kinds']
    return {kind: [a.get(kind, 0), b.get(kind, 0)] for kind in sorted(set(a) | set(b))
            if kind != 'success' and a.get(kind, 0) != b.get(kind, 0)}


def constant_row(entry, nominal_rows, end_rows):
    """One constant in one case and speed: the three cells, each end's test against the nominal
    and its moved failure kinds, and the swing (largest minus smallest of the three rates)."""
    row = {'key': entry['key'], 'name': entry['name'], 'kind': entry['kind'],
           'unit': entry['unit'], 'source': entry['source'], 'low': entry['low'],
           'nominal': entry['nominal'], 'high': entry['high'],
           'nominal_cell': success_cell(nominal_rows)}
    for end in ENDS:
        row[end + '_cell'] = success_cell(end_rows[end])
        row[end + '_test'] = paired_test(end_rows[end], nominal_rows)
        row[end + '_moved'] = moved_kinds(row[end + '_cell'], row['nominal_cell'])
        row[end + '_is_nominal'] = same_value(entry[end], entry['nominal'])
    rates = [rate(row[k + '_cell']) for k in ('low', 'nominal', 'high')]
    rates = [r for r in rates if r is not None]
    row['swing'] = max(rates) - min(rates) if rates else 0.0
    return row


def sensitivity_table(entries, results, cases, rpms):
    """[{case, rpm, rows}] per case and speed; rows sorted by the largest swing first."""
    groups = []
    for rpm in rpms:
        for case in cases:
            rows = []
            for entry in entries:
                ends = {end: _group(results[bench_id(entry, end)], case, rpm) for end in ENDS}
                rows.append(constant_row(entry, _group(results['nominal'], case, rpm), ends))
            rows.sort(key=lambda r: (-r['swing'], r['key']))
            groups.append({'case': case, 'rpm': rpm, 'rows': rows})
    return groups


# --- the conclusions ---------------------------------------------------------------------------

def _verdict(holds, detail):
    return {'holds': holds, 'detail': detail}


def _paired_verdict(rows, rpms, case_a, case_b, holds):
    """At every speed, `holds(only_a, only_b, p)` on the trials of the two cases paired by seed."""
    verdict, details = True, []
    for rpm in rpms:
        a, b = _group(rows, case_a, rpm), _group(rows, case_b, rpm)
        if not a or not b:
            return _verdict(None, 'no %s or %s trials at %.0f rpm' % (case_a, case_b, rpm))
        pairs, both, only_a, only_b, _ = stats.paired_counts(a, b, key=lambda r: r['seed'])
        if pairs == 0:
            errors = [r.get('error') for r in a + b if r.get('error')]
            return _verdict(None, '%.0f rpm: no %s and %s pair without an error%s' % (
                rpm, case_a, case_b, (' (%d errored: %s)' % (len(errors), errors[0]))
                if errors else ''))
        p = stats.mcnemar_exact(only_a, only_b)
        verdict = verdict and holds(only_a, only_b, p)
        details.append('%.0f rpm: %s %d/%d, %s %d/%d, McNemar p = %.2g' % (
            rpm, case_a, both + only_a, pairs, case_b, both + only_b, pairs, p))
    return _verdict(verdict, '; '.join(details))


def compensated_equals_stationary(rows, rpms):
    """At every speed, no significant difference between the compensated and the stationary
    trials of the same seeds (McNemar's exact p >= ALPHA)."""
    return _paired_verdict(rows, rpms, 'compensated', 'stationary',
                           lambda only_a, only_b, p: p >= ALPHA)


def compensated_beats_uncompensated(rows, rpms):
    """At every speed, more compensated than uncompensated successes on the same seeds, and
    significantly so (McNemar's exact p < ALPHA)."""
    return _paired_verdict(rows, rpms, 'compensated', 'uncompensated',
                           lambda only_a, only_b, p: only_a > only_b and p < ALPHA)


def _speed_tests(rows, rpms):
    """[(rpm, successes, trials, p)] of the SPEED_CASE at each speed other than BEST_RPM, with
    Fisher's exact p against BEST_RPM (speeds draw different specimens: independent samples),
    and BEST_RPM's (successes, trials); None when fewer than two speeds or no BEST_RPM."""
    if BEST_RPM not in rpms or len(rpms) < 2:
        return None

    def cell(rpm):
        valid = [r for r in _group(rows, SPEED_CASE, rpm) if not r.get('error')]
        return sum(1 for r in valid if r['success']), len(valid)
    best = cell(BEST_RPM)
    others = [(rpm,) + cell(rpm) for rpm in rpms if rpm != BEST_RPM]
    return best, [(rpm, k, n, stats.fisher_exact(best[0], best[1], k, n))
                  for rpm, k, n in others]


def _speed_detail(best, others):
    return '%s %d/%d at %.0f rpm; ' % (SPEED_CASE, best[0], best[1], BEST_RPM) + '; '.join(
        '%d/%d at %.0f rpm (Fisher p = %.2g)' % (k, n, rpm, p) for rpm, k, n, p in others)


def _higher(k_a, n_a, k_b, n_b):
    return n_a > 0 and (n_b == 0 or k_a * n_b > k_b * n_a)


def best_speed_not_beaten(rows, rpms):
    """'12000 rpm is the best speed': no other speed has a higher success rate of the
    compensated case with Fisher's exact p < ALPHA. None without several speeds."""
    tests = _speed_tests(rows, rpms)
    if tests is None:
        return _verdict(None, 'needs several speeds, %.0f rpm among them' % BEST_RPM)
    best, others = tests
    beaten = [t for t in others if _higher(t[1], t[2], best[0], best[1]) and t[3] < ALPHA]
    return _verdict(not beaten, _speed_detail(best, others))


def best_speed_significantly(rows, rpms):
    """The paper's drop with speed (Fig. 15): 12000 rpm has a higher compensated success rate
    than every other speed, each with Fisher's exact p < ALPHA. None without several speeds."""
    tests = _speed_tests(rows, rpms)
    if tests is None:
        return _verdict(None, 'needs several speeds, %.0f rpm among them' % BEST_RPM)
    best, others = tests
    better = all(_higher(best[0], best[1], t[1], t[2]) and t[3] < ALPHA for t in others)
    return _verdict(better, _speed_detail(best, others))


CONCLUSIONS = (
    ('compensated_equals_stationary', 'Compensated equals stationary',
     'no significant difference (McNemar\'s exact p >= %g) between compensated and stationary on '
     'the same seeds, at every speed' % ALPHA, compensated_equals_stationary),
    ('compensated_beats_uncompensated', 'Compensated beats uncompensated',
     'more compensated than uncompensated successes on the same seeds, McNemar\'s exact p < %g, '
     'at every speed' % ALPHA, compensated_beats_uncompensated),
    ('best_speed', '12000 rpm is the best speed',
     'no other speed has a higher compensated success rate with Fisher\'s exact p < %g' % ALPHA,
     best_speed_not_beaten),
    ('best_speed_significantly', '12000 rpm is significantly the best speed (Fig. 15\'s drop)',
     'the compensated success rate at 12000 rpm is higher than at every other speed, each with '
     'Fisher\'s exact p < %g' % ALPHA, best_speed_significantly),
)


def conclusions(results, benches, rpms):
    """Per conclusion: its verdict at the nominal bench and at every swept end (an end at the
    nominal value is the nominal bench), and the ends where it fails."""
    out = []
    for ident, title, rule, test in CONCLUSIONS:
        nominal = test(results['nominal'], rpms)
        ends = []
        for condition in benches:
            if condition['scenario'] is None or condition['entry'] is None:
                continue  # the nominal bench itself
            verdict = test(results[condition['id']], rpms)
            ends.append(dict(verdict, id=condition['id'], key=condition['entry']['key'],
                             end=condition['end'], value=condition['value']))
        out.append({'id': ident, 'title': title, 'rule': rule, 'nominal': nominal, 'ends': ends,
                    'fails_at': [e for e in ends if e['holds'] is False],
                    'holds_over_range': overall(nominal, ends)})
    return out


def overall(nominal, ends):
    """True when a conclusion holds at the nominal bench and at every end, False when it fails
    at any, None when it cannot be evaluated (at the nominal bench or at an end)."""
    verdicts = [nominal['holds']] + [e['holds'] for e in ends]
    if False in verdicts:
        return False
    return None if None in verdicts else True
