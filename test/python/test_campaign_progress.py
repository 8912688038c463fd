"""The campaign's progress display: a bar in place on a terminal, whole lines
elsewhere (a file, a pipe, Slurm's log), no carriage return there."""
import io


from pd_campaign.progress import Progress  # noqa: E402


def test_progress_writes_lines_when_not_a_terminal():
    out = io.StringIO()  # isatty() is False, as for a log file
    progress = Progress(600, stream=out)
    for k in range(600):
        progress.update({'error': 'x' if k == 3 else ''})
    text = out.getvalue()
    assert '\r' not in text
    lines = text.splitlines()
    assert text.endswith('\n')
    # One per tenth of the trials (this loop takes far less than 30 s), the last at 600/600.
    assert 10 <= len(lines) <= 11, lines
    assert lines[0].startswith('campaign: 60/600 trials (1 errors)')
    assert lines[-1].startswith('campaign: 600/600 trials (1 errors)')


def test_progress_writes_a_line_every_30_s_between_tenths():
    out = io.StringIO()
    progress = Progress(1000, stream=out)
    progress.update({})
    assert out.getvalue() == ''
    progress.last_line -= Progress.LINE_EVERY_S  # 30 s went by
    progress.update({})
    assert out.getvalue().startswith('campaign: 2/1000 trials (0 errors)')


def test_progress_redraws_one_line_on_a_terminal():
    out = io.StringIO()
    progress = Progress(3, stream=out, interactive=True)
    for _ in range(3):
        progress.update({})
    text = out.getvalue()
    assert text.count('\r') == 3 and '\n' not in text
    assert '3/3 trials (0 errors)' in text
