"""Every output file of the scripts is written to a temporary file and renamed:
pd_campaign.atomic on its own (a write that fails midway leaves the old file and no temporary
one), the scripts' source (no output opened for writing any other way), and the scripts run
under an audit hook that sees every file they open for writing."""
import ast
import glob
import json
import os
import re
import stat
import subprocess
import sys
import textwrap

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
SCRIPTS = os.path.join(ROOT, 'scripts')
PACKAGE_SRC = os.path.join(ROOT, 'src')  # pd_campaign's sources, scanned (imported from the workspace)
from pd_campaign.atomic import atomic_path, atomic_savefig, atomic_write  # noqa: E402

# The helper's temporary files: .<name>.tmp<random> in the destination's folder.
TEMPORARY = re.compile(r'^\..+\.tmp[A-Za-z0-9_]+$')


class Midway(Exception):
    pass


def _listing(folder):
    return sorted(os.listdir(str(folder)))


# --- the helper -----------------------------------------------------------------------------

def test_a_complete_write_replaces_the_file_with_the_usual_mode(tmp_path):
    path = tmp_path / 'summary.json'
    path.write_text('old\n')
    with atomic_write(str(path)) as handle:
        handle.write('new\n')
        assert path.read_text() == 'old\n', 'the destination changes only at the rename'
    assert path.read_text() == 'new\n'
    assert stat.S_IMODE(os.stat(str(path)).st_mode) == 0o644
    assert _listing(tmp_path) == ['summary.json']


@pytest.mark.parametrize('error', [Midway, KeyboardInterrupt])
def test_a_write_that_raises_midway_leaves_the_old_file_and_no_temporary(tmp_path, error):
    path = tmp_path / 'trials.csv'
    path.write_text('header\nrow 1\n')
    with pytest.raises(error):
        with atomic_write(str(path), newline='') as handle:
            handle.write('header\nrow 1\nrow 2 (half')
            handle.flush()
            raise error()
    assert path.read_text() == 'header\nrow 1\n'
    assert _listing(tmp_path) == ['trials.csv']


def test_a_first_write_that_raises_leaves_no_file(tmp_path):
    with pytest.raises(Midway):
        with atomic_write(str(tmp_path / 'report.md')) as handle:
            handle.write('# Report (half')
            raise Midway()
    assert _listing(tmp_path) == []


def test_a_writer_that_opens_the_file_itself_gets_a_temporary_path(tmp_path):
    path = tmp_path / 'volunteer_1.bag'
    path.write_bytes(b'old bag')
    with pytest.raises(Midway):
        with atomic_path(str(path)) as tmp:
            assert os.path.dirname(tmp) == str(tmp_path)
            assert TEMPORARY.match(os.path.basename(tmp)), tmp
            with open(tmp, 'wb') as handle:
                handle.write(b'half a bag')
            raise Midway()
    assert path.read_bytes() == b'old bag'
    assert _listing(tmp_path) == ['volunteer_1.bag']
    with atomic_path(str(path)) as tmp:
        with open(tmp, 'wb') as handle:
            handle.write(b'new bag')
    assert path.read_bytes() == b'new bag'
    assert _listing(tmp_path) == ['volunteer_1.bag']


def test_a_figure_is_saved_whole_or_not_at_all(tmp_path):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    path = tmp_path / 'fig15_success_vs_speed.png'
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    atomic_savefig(fig, str(path), dpi=50)
    good = path.read_bytes()
    assert good.startswith(b'\x89PNG\r\n\x1a\n')

    def fails_midway(handle, **kwargs):
        handle.write(good[:100])
        raise Midway()
    fig.savefig = fails_midway
    with pytest.raises(Midway):
        atomic_savefig(fig, str(path), dpi=50)
    plt.close(fig)
    assert path.read_bytes() == good
    assert _listing(tmp_path) == ['fig15_success_vs_speed.png']


def test_a_write_that_fails_names_the_output_not_its_temporary_file(tmp_path):
    """A full disk (an OSError of the writer that names no file), a rename that fails (here onto
    a folder) and a missing folder name the output; an error of another file (a copy's missing
    source) keeps its own name. The old file stays, no temporary file."""
    import errno
    import shutil
    path = tmp_path / 'summary.json'
    path.write_text('old\n')
    with pytest.raises(OSError) as full:
        with atomic_write(str(path)) as handle:
            handle.write('new')
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    assert (full.value.errno, full.value.filename) == (errno.ENOSPC, str(path))
    (tmp_path / 'report.md').mkdir()
    with pytest.raises(IsADirectoryError) as onto_folder:
        with atomic_write(str(tmp_path / 'report.md')) as handle:
            handle.write('new')
    assert onto_folder.value.filename == str(tmp_path / 'report.md')
    assert onto_folder.value.filename2 is None
    with pytest.raises(FileNotFoundError) as nowhere:
        with atomic_write(str(tmp_path / 'nowhere' / 'design.json')):
            pass
    assert nowhere.value.filename == str(tmp_path / 'nowhere' / 'design.json')
    with pytest.raises(FileNotFoundError) as missing:
        with atomic_path(str(path)) as tmp:
            shutil.copyfile(str(tmp_path / 'absent.md'), tmp)
    assert missing.value.filename == str(tmp_path / 'absent.md')
    assert path.read_text() == 'old\n'
    assert _listing(tmp_path) == ['report.md', 'summary.json']


def test_the_temporary_files_a_kill_left_are_removed_and_nothing_else(tmp_path):
    from pd_campaign.atomic import remove_temporaries
    for name in ('.trials.csv.tmpab_d12x9', '.x.npy.tmpQ1w2E3', 'trials.csv', '.hidden',
                 'a.tmp12345678', '.b.tmp'):
        (tmp_path / name).write_text('x')
    remove_temporaries(str(tmp_path))
    assert _listing(tmp_path) == ['.b.tmp', '.hidden', 'a.tmp12345678', 'trials.csv']


def test_an_output_in_a_missing_folder_fails_and_creates_nothing(tmp_path):
    with pytest.raises(FileNotFoundError):
        with atomic_write(str(tmp_path / 'nowhere' / 'design.json')):
            pass
    assert _listing(tmp_path) == []


def test_a_mode_that_does_not_write_a_new_file_is_refused(tmp_path):
    with pytest.raises(ValueError):
        with atomic_write(str(tmp_path / 'trials.csv'), 'a'):
            pass
    assert _listing(tmp_path) == []


# --- the scripts' source ----------------------------------------------------------------------

EXEMPT = '# not atomic:'  # on the line of a write that is deliberately not atomic, with why
SAVE_CALLS = {'savefig', 'imsave', 'savetxt', 'savez', 'savez_compressed', 'to_csv',
              'write_text', 'write_bytes'}
SHUTIL_WRITERS = {'copy', 'copy2', 'copyfile', 'move', 'copytree'}
RENAMES = {'replace', 'rename', 'renames'}


def _mode(call, position, default):
    if len(call.args) > position:
        node = call.args[position]
    else:
        node = next((k.value for k in call.keywords if k.arg == 'mode'), None)
        if node is None:
            return default
    return node.value if isinstance(node, ast.Constant) and isinstance(node.value, str) else None


def _argument(call, position, keyword):
    if len(call.args) > position:
        return call.args[position]
    return next((k.value for k in call.keywords if k.arg == keyword), None)


def output_violations(source):
    """(line, what) of each place `source` writes a file other than through pd_campaign.atomic:
    open() for writing, a figure or array saved to a path, shutil copying to a path, a rosbag
    opened for writing or a rename by hand. Writing to a path bound by `with atomic_path(...) as
    NAME` is fine, and so is an array or figure saved into the handle of `with atomic_write(...)
    as NAME`, and a line marked `# not atomic: <why>`."""
    tree = ast.parse(source)
    lines = source.splitlines()
    def bound_by(function):
        return {item.optional_vars.id for node in ast.walk(tree) if isinstance(node, ast.With)
                for item in node.items
                if isinstance(item.context_expr, ast.Call)
                and getattr(item.context_expr.func, 'id', None) == function
                and isinstance(item.optional_vars, ast.Name)}
    temporary = bound_by('atomic_path')
    handles = bound_by('atomic_write')  # an array or figure saved into its handle is atomic

    def to_temporary(node):
        return isinstance(node, ast.Name) and node.id in temporary

    found = []
    for call in ast.walk(tree):
        if not isinstance(call, ast.Call) or EXEMPT in lines[call.lineno - 1]:
            continue
        func = call.func
        name = func.id if isinstance(func, ast.Name) else getattr(func, 'attr', None)
        owner = func.value.id if isinstance(func, ast.Attribute) and isinstance(
            func.value, ast.Name) else None
        if name == 'open' and owner in (None, 'io', 'codecs'):
            mode = _mode(call, 1, 'r')
            if (mode is None or set(mode) & set('wax+')) and not to_temporary(call.args[0]):
                found.append((call.lineno, 'open(..., %r)' % mode))
        elif name in ('open', 'fdopen') and owner == 'os':
            found.append((call.lineno, 'os.%s' % name))
        elif name in SAVE_CALLS:
            target = call.args[0] if call.args else None
            if not (to_temporary(target) or (isinstance(target, ast.Name)
                                             and target.id in handles)):
                found.append((call.lineno, name))
        elif owner == 'shutil' and name in SHUTIL_WRITERS:
            if not to_temporary(_argument(call, 1, 'dst')):
                found.append((call.lineno, 'shutil.%s' % name))
        elif owner == 'os' and name in RENAMES:
            found.append((call.lineno, 'os.%s by hand' % name))
        elif name == 'Bag':
            mode = _mode(call, 1, 'r')
            if (mode is None or mode != 'r') and not to_temporary(_argument(call, 0, 'f')):
                found.append((call.lineno, 'rosbag.Bag(..., %r)' % mode))
    return sorted(found)


def python_scripts():
    paths = []
    for path in sorted(glob.glob(os.path.join(SCRIPTS, '*')) +
                       glob.glob(os.path.join(SCRIPTS, 'dev', '*')) +
                       glob.glob(os.path.join(PACKAGE_SRC, 'pd_campaign', '**', '*.py'),
                                 recursive=True)):
        if not os.path.isfile(path) or path.endswith(os.path.join('pd_campaign', 'atomic.py')):
            continue
        with open(path, errors='replace') as handle:
            first = handle.readline()
        if path.endswith('.py') or ('python' in first and first.startswith('#!')):
            paths.append(path)
    return paths


def test_the_source_check_finds_every_kind_of_direct_write():
    source = textwrap.dedent('''
        import os, shutil, rosbag
        open(path, 'w')
        open(path, mode='a')
        open(path, 'rb+')
        open(path, mode)
        io.open(path, 'wb')
        os.open(path, os.O_WRONLY)
        fig.savefig(path, dpi=100)
        np.savetxt(path, data)
        pathlib.Path(path).write_text('x')
        shutil.copyfile(a, b)
        os.replace(a, b)
        rosbag.Bag(path, 'w')
        ''')
    assert [line for line, _ in output_violations(source)] == list(range(3, 15))


def test_the_source_check_accepts_the_atomic_forms_and_reads():
    source = textwrap.dedent('''
        with open(path) as src, atomic_write(dst) as handle:
            handle.write(src.read())
        with atomic_write(npz, 'wb') as out:
            np.savez_compressed(out, a=a)
        with open(path, 'rb') as handle:
            pass
        atomic_savefig(fig, path, dpi=100)
        with atomic_path(bag_path) as tmp:
            with rosbag.Bag(tmp, 'w') as bag:
                pass
            shutil.copyfile(source, tmp)
            open(tmp, 'w').close()
        rosbag.Bag(path)
        log = open(path, 'w')  # not atomic: a live log, appended as the run goes
        ''')
    assert output_violations(source) == []


@pytest.mark.parametrize('path', python_scripts(), ids=os.path.basename)
def test_no_script_opens_an_output_for_writing_directly(path):
    with open(path) as handle:
        found = output_violations(handle.read())
    assert not found, '%s writes outside pd_campaign.atomic (atomic_write, atomic_savefig, ' \
        'atomic_path; or mark a deliberate exception "%s <why>"): %s' % (
            os.path.relpath(path, ROOT), EXEMPT, found)


def test_the_check_covers_the_scripts_named_by_the_issue():
    names = {os.path.relpath(p, SCRIPTS) if p.startswith(SCRIPTS)
             else os.path.relpath(p, PACKAGE_SRC) for p in python_scripts()}
    for name in ('table2.py', 'plot_tidal_volume.py', 'volunteers_to_bag.py', 'campaign',
                 'campaign_merge', 'campaign_compare', 'pd_campaign/cli.py',
                 'pd_campaign/report.py', 'pd_campaign/plots.py', 'pd_campaign/compare.py',
                 'pd_campaign/worker.py', 'pd_campaign/trials_csv.py', 'pd_campaign/aggregate.py',
                 'pd_campaign/sensitivity/outputs.py'):
        assert name in names


# --- the scripts, run ---------------------------------------------------------------------------

# Runs a script with an audit hook that records every file opened for writing (by the script,
# matplotlib, PIL, shutil, rosbag: any Python code of the process) under a watched folder.
HOOKED = textwrap.dedent(r'''
    import atexit, json, os, runpy, sys
    WATCHED = os.path.realpath(os.environ['ATOMIC_WATCH']) + os.sep
    WRITE = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_APPEND
    written = []

    def hook(event, args):
        if event == 'open' and isinstance(args[0], str) and args[2] & WRITE:
            path = os.path.realpath(args[0])
            if path.startswith(WATCHED):
                written.append(path)

    def report():
        with open(os.environ['ATOMIC_LOG'], 'w') as handle:
            json.dump(written, handle)

    atexit.register(report)
    sys.addaudithook(hook)
    script = sys.argv[1]
    sys.argv = sys.argv[1:]
    sys.path.insert(0, os.path.dirname(os.path.realpath(script)))
    runpy.run_path(script, run_name='__main__')
    ''')


def run_hooked(tmp_path, script, *args):
    log = str(tmp_path / ('written-%s.json' % script))
    env = dict(os.environ, ATOMIC_WATCH=str(tmp_path / 'out'), ATOMIC_LOG=log)
    result = subprocess.run(['/usr/bin/python3', '-c', HOOKED, os.path.join(SCRIPTS, script)]
                            + list(args), capture_output=True, text=True, env=env,
                            timeout=300)
    assert result.returncode == 0, (script, result.stdout[-2000:], result.stderr[-3000:])
    with open(log) as handle:
        return json.load(handle)


def test_the_scripts_write_every_output_through_a_temporary_file(tmp_path, bin_dir):
    out = tmp_path / 'out'
    out.mkdir()
    written = {}
    camp, merged = str(out / 'campaign'), str(out / 'merged')
    written['campaign'] = run_hooked(
        tmp_path, 'campaign', '--case', 'stationary', '--rpm', '12000', '--trials', '1',
        '--jobs', '1', '--seed', '3', '--engine', 'core', '--out', camp)
    written['campaign_merge'] = run_hooked(tmp_path, 'campaign_merge', camp, '--out', merged)
    written['campaign_compare'] = run_hooked(tmp_path, 'campaign_compare', camp, camp,
                                             '--label-a', 'a', '--label-b', 'b',
                                             '--out', str(out / 'compare'))
    written['table2.py'] = run_hooked(tmp_path, 'table2.py', '--out', str(out / 'table2'),
                                      '--jobs', '2')
    written['volunteers_to_bag.py'] = run_hooked(
        tmp_path, 'volunteers_to_bag.py', '--csv-dir', str(out / 'table2' / 'data'),
        '--out', str(out / 'bags'), '--ids', '1')
    tv_csv = tmp_path / 'tv.csv'
    with open(str(tv_csv), 'w') as handle:
        subprocess.run([os.path.join(bin_dir, 'tidal_volume'), '--duration', '10'],
                       stdout=handle, check=True, timeout=60)
    written['plot_tidal_volume.py'] = run_hooked(tmp_path, 'plot_tidal_volume.py',
                                                 str(tv_csv), str(out / 'tidal_volume.png'))
    # The live trials.csv of a running campaign is appended trial by trial on purpose, then
    # rewritten atomically at the end, and its folder's lock file holds the lock (and a pid);
    # everything else goes through a temporary file.
    live = [os.path.realpath(os.path.join(camp, name)) for name in ('trials.csv', 'campaign.lock')]
    for script, paths in written.items():
        assert paths, '%s wrote nothing under the watched folder' % script
        direct = [p for p in paths if not TEMPORARY.match(os.path.basename(p))
                  and not (script == 'campaign' and p in live)]
        assert not direct, '%s opened outputs for writing directly: %s' % (script, direct)
    kept = []
    for folder, _, names in os.walk(str(out)):
        assert not [n for n in names if '.tmp' in n], (folder, names)
        kept += [os.path.relpath(os.path.join(folder, n), str(out)) for n in names]
    for name in ('campaign/trials.csv', 'campaign/summary.json', 'campaign/report.md',
                 'campaign/design.json', 'campaign/table2.md', 'campaign/table3.png',
                 'campaign/traces/stationary-12000-000.json', 'merged/report.md',
                 'merged/traces/stationary-12000-000.json', 'merged/table2.csv',
                 'compare/compare.md', 'compare/compare.png', 'table2/table2.csv',
                 'table2/table2_fig14.png', 'bags/volunteer_1.bag', 'tidal_volume.png'):
        assert name in kept, name
