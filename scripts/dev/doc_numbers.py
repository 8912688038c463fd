"""The documents' generated numbers: a number in a sentence, from the archived results.

A generated number is written `<!-- n: SPEC -->TEXT<!-- /n -->` in a document (the comment is
invisible once rendered); make_docs.py rewrites TEXT from the archive in doc/results/ and
`make_docs.py --check` fails when TEXT differs. SPEC is one of:

- `FOLDER CASE RPM KEY [FORMAT]`: the value KEY of the group (CASE, RPM) of FOLDER/summary.json;
  KEY is a dotted path into the group (`median_f_out_n`, `quartiles_f_in_n.1`,
  `failure_kinds.breakthrough_before_stop`; a missing dictionary key is 0, a count that did not
  occur); FORMAT a format() spec (`.2f`, `.0f`, `d`; `.0%` writes a rate as `28 %`, with the
  documents' space), by default str();
- `FOLDER CASE RPM count COLUMN=VALUE[,COLUMN=VALUE...]`: how many rows of FOLDER/trials.csv of
  that case and speed have every COLUMN equal to VALUE;
- `FOLDER CASE RPM max COLUMN[-COLUMN] FORMAT WHERE COLUMN=VALUE[,...]`: the largest value
  (or difference of two columns) over those rows, formatted;
- `FOLDER CASE RPM fisher K/N FORMAT`: Fisher's exact test (two-sided) of the group's successes
  against K of N (the paper's count);
- `FOLDER CASE RPM mcnemar OTHER_CASE FORMAT`: McNemar's exact test of the case against
  OTHER_CASE paired by seed index (trials.csv's success); OTHER_CASE may be
  `OTHER_FOLDER:OTHER_CASE`, the case of another campaign on the same seeds;
- `FOLDER CASE RPM only OTHER_CASE`: how many seeds succeed in CASE and not in OTHER_CASE (or
  `OTHER_FOLDER:OTHER_CASE`);
- `FOLDER CASE RPM change KEY FORMAT`: the group's KEY against the stationary group's at the same
  speed, in per cent (-43 for a value 43 % lower);
- `FOLDER CASE RPM sweep CONSTANT COLUMN [FORMAT]`: the column COLUMN (`successes_high`,
  `mcnemar_p_low`, ...) of the row of FOLDER/sensitivity.csv (campaign_sensitivity's) for that
  case, speed and swept constant.

CASE may be `CASE/FAULT`: the group of that case and fault in summary.json's `faults` (the fault
campaign's per-fault summary) instead of its `groups`.
"""
import csv
import json
import os
import re
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', 'src'))
from pd_campaign import stats  # noqa: E402

# TEXT is a number's text: on one line, without a backtick or an angle bracket (so that a
# document may quote the syntax in code).
NUMBER = re.compile(r'(<!-- n: ([^>\n]*?) -->)([^<>`\n]*?)(<!-- /n -->)')


def _group(archive, folder, case, rpm):
    with open(os.path.join(archive, folder, 'summary.json')) as handle:
        summary = json.load(handle)
    case, _, fault = case.partition('/')
    groups = [g for g in summary['faults'] if g['fault'] == fault] if fault else summary['groups']
    found = [g for g in groups if g['case'] == case and float(g['rpm']) == float(rpm)]
    if len(found) != 1:
        raise KeyError('%s/summary.json: no group %s at %s rpm' % (folder, case, rpm))
    return found[0]


def _rows(archive, folder, case, rpm, conditions):
    with open(os.path.join(archive, folder, 'trials.csv')) as handle:
        rows = [r for r in csv.DictReader(handle)
                if r['case'] == case and float(r['rpm']) == float(rpm)]
    for condition in conditions.split(',') if conditions else []:
        column, value = condition.split('=', 1)
        rows = [r for r in rows if r[column] == value]
    return rows


def _discordant(archive, folder, case, other, rpm):
    """(seeds that succeed in `case` only, in `other` only), paired by seed index."""
    other_folder, _, other_case = other.rpartition(':')
    mine = {r['index']: r['success'] == 'true' for r in _rows(archive, folder, case, rpm, '')}
    theirs = {r['index']: r['success'] == 'true'
              for r in _rows(archive, other_folder or folder, other_case, rpm, '')}
    pairs = [(mine[i], theirs[i]) for i in mine if i in theirs]
    return sum(a and not b for a, b in pairs), sum(b and not a for a, b in pairs)


def _sweep(archive, folder, case, rpm, constant, column):
    with open(os.path.join(archive, folder, 'sensitivity.csv')) as handle:
        found = [r for r in csv.DictReader(handle) if r['case'] == case
                 and float(r['rpm']) == float(rpm) and r['constant'] == constant]
    if len(found) != 1:
        raise KeyError('%s/sensitivity.csv: no row %s at %s rpm for %s' % (folder, case, rpm,
                                                                          constant))
    return found[0][column]


def _formatted(result, spec_format):
    """`result` formatted by `spec_format` (a rate as `28 %` for `.0%`)."""
    text = format(result, spec_format)
    return text[:-1] + ' %' if spec_format.endswith('%') else text


def _lookup(group, key):
    value = group
    for part in key.split('.'):
        if isinstance(value, list):
            value = value[int(part)]
        elif isinstance(value, dict):
            value = value.get(part, 0)
        else:
            raise KeyError('%s: %r is not a dictionary or list' % (key, value))
    return value


def value(spec, archive):
    """The text of the generated number `spec` (see the module's description) from `archive`."""
    words = spec.split()
    if len(words) < 4:
        raise ValueError('generated number %r: FOLDER CASE RPM KEY ... expected' % spec)
    folder, case, rpm, key = words[:4]
    if key == 'count':
        return str(len(_rows(archive, folder, case, rpm, words[4] if len(words) > 4 else '')))
    if key == 'fisher':
        group = _group(archive, folder, case, rpm)
        paper_successes, paper_trials = (int(x) for x in words[4].split('/'))
        return _formatted(stats.fisher_exact(group['successes'], group['trials'],
                                             paper_successes, paper_trials), words[5])
    if key in ('mcnemar', 'only'):
        only_a, only_b = _discordant(archive, folder, case, words[4], rpm)
        return (_formatted(stats.mcnemar_exact(only_a, only_b), words[5]) if key == 'mcnemar'
                else str(only_a))
    if key == 'change':
        reference = _lookup(_group(archive, folder, 'stationary', rpm), words[4])
        mine = _lookup(_group(archive, folder, case, rpm), words[4])
        return _formatted(100.0 * (mine / reference - 1.0), words[5])
    if key == 'max':
        columns, spec_format = words[4], words[5]
        where = words[7] if len(words) > 7 and words[6] == 'WHERE' else ''
        first, _, second = columns.partition('-')
        values = [float(r[first]) - (float(r[second]) if second else 0.0)
                  for r in _rows(archive, folder, case, rpm, where)]
        return _formatted(max(values), spec_format)
    if key == 'sweep':
        text = _sweep(archive, folder, case, rpm, words[4], words[5])
        return _formatted(float(text), words[6]) if len(words) > 6 else text
    result = _lookup(_group(archive, folder, case, rpm), key)
    return str(result) if len(words) == 4 else _formatted(result, words[4])


def regenerate(text, archive):
    """`text` with every generated number rewritten from `archive`; and their specs."""
    specs = []

    def rebuilt(match):
        specs.append(match.group(2))
        return match.group(1) + value(match.group(2), archive) + match.group(4)
    return NUMBER.sub(rebuilt, text), specs
