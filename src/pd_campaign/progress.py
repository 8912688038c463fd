"""A campaign's progress on stderr (trials done, errors, elapsed time, ETA) and the clock text
that campaign_sensitivity's lines use as well."""
import sys
import time


def clock(seconds):
    """`M:SS` of a duration in seconds (minutes unbounded)."""
    seconds = int(seconds)
    return '%d:%02d' % (seconds // 60, seconds % 60)


class Progress:
    """Progress with ETA on stderr: a bar redrawn in place on a terminal; on anything else (a
    file, a pipe, Slurm's log) whole lines, one per tenth of the trials or per 30 s, whichever
    comes first, and the last."""

    LINE_EVERY_S = 30.0

    def __init__(self, total, stream=None, interactive=None):
        self.total = total
        self.done = 0
        self.failed = 0
        self.start = time.time()
        self.stream = sys.stderr if stream is None else stream
        self.interactive = (self.stream.isatty() if interactive is None else interactive)
        self.last_line = self.start
        self.last_tenth = 0

    def update(self, row):
        self.done += 1
        if row.get('error'):
            self.failed += 1
        now = time.time()
        elapsed = now - self.start
        eta = elapsed / self.done * (self.total - self.done) if self.done else 0
        if self.interactive:
            width = 30
            filled = int(width * self.done / max(1, self.total))
            self.stream.write('\r[%s%s] %d/%d trials (%d errors)  elapsed %s  ETA %s   ' % (
                '#' * filled, '.' * (width - filled), self.done, self.total, self.failed,
                clock(elapsed), clock(eta)))
        else:
            tenth = 10 * self.done // max(1, self.total)
            if (tenth == self.last_tenth and self.done < self.total and
                    now - self.last_line < self.LINE_EVERY_S):
                return
            self.last_tenth = tenth
            self.last_line = now
            self.stream.write('campaign: %d/%d trials (%d errors), elapsed %s, ETA %s\n' % (
                self.done, self.total, self.failed, clock(elapsed), clock(eta)))
        self.stream.flush()
