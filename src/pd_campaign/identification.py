"""The Table II identification of the five virtual volunteers (table2.py) that campaigns use:
its files, the check that a folder holds them all, and one run of it for a sweep of campaigns
(campaign_sensitivity, campaign_robustness, campaign_leaderboard)."""
import os
import subprocess

from . import tools

# Table II files a campaign copies from its identification; shards share them.
TABLE2_FILES = ('table2.md', 'table2.csv')
TABLE2_VOLUNTEERS = (1, 2, 3, 4, 5)  # table2.py's IDS: the five virtual volunteers' models
IDENTIFICATION_DIR = 'identification'


class IdentificationError(RuntimeError):
    """The sweep's one Table II identification (table2.py) failed."""


def identification_files():
    """The files of a Table II identification a campaign uses: TABLE2_FILES and each
    volunteer's linear and hysteresis model."""
    return list(TABLE2_FILES) + [os.path.join('models', 'volunteer_%d_%s.yaml' % (v, kind))
                                 for v in TABLE2_VOLUNTEERS for kind in ('linear', 'hysteresis')]


def check_identification(directory):
    """The first file a Table II identification directory lacks (None: complete)."""
    return next((name for name in identification_files()
                 if not os.path.isfile(os.path.join(directory, name))), None)


def identify(out, jobs):
    """Table II once for a whole sweep, into OUT/identification (the campaigns read it with
    --identification: it takes no scenario setting, so every bench's campaign would identify the
    same models). Raises IdentificationError with table2.py's message when it fails."""
    directory = os.path.join(out, IDENTIFICATION_DIR)
    result = subprocess.run(tools.tool('table2.py') + ['--out', directory, '--jobs', str(jobs),
                                                       '--no-figure'],
                            capture_output=True, text=True)
    if result.returncode != 0:
        raise IdentificationError('the Table II identification failed:\n%s'
                                  % (result.stderr or result.stdout))
    return directory
