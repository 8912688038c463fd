"""Sensitivity of the campaign's conclusions to the bench's uncertain constants.

    rosrun pedicle_drilling campaign_sensitivity [--scenario FILE] [--sweep FILE] [--rpm R,...]
        [--trials N] [--seed S] [--seed-space SPACE] [--jobs J] [--out DIR] [--only NAME ...]

One constant at a time goes to each end of its documented range (config/sensitivity.yaml), every
other constant stays at the nominal bench (the scenario). Each bench is one campaign, run by the
campaign itself (scripts/campaign) into a subdirectory of --out: `nominal` and
`<kind>.<name>-low` / `-high`, all on the same seeds (a trial's seed depends on the base seed,
the seed space, the speed and the index only, design.py), so every end is paired with the
nominal bench trial by trial. An end equal to the nominal value uses the nominal campaign. A
subdirectory that already holds the finished campaign of the same scenario and design, run by
the same build (tools.build_id: the trial_engine executable, the package's libraries and this
Python package's sources; its build.json), is kept (the sweep resumes). Written to --out,
each through a temporary file: sensitivity.md (per case and speed, one row per constant, sorted
by the largest swing: success at low, nominal and high with Wilson 95 % intervals, McNemar's
exact p of each end against the nominal, the failure kinds that moved; then the verdict of each
conclusion at the nominal bench and at every swept end), sensitivity.csv, sensitivity.json and
sensitivity.png (a tornado plot per case and speed).

The sub-package's modules, their public names imported here (`from pd_campaign import
sensitivity` reads them all): sweep (the sweep file and its benches), runner (the benches'
campaigns run), verdicts (the table and the conclusions), outputs (the files written) and command
(the command line, main; also `python3 -m pd_campaign.sensitivity`).
"""
from ..identification import IDENTIFICATION_DIR, IdentificationError, identify  # noqa: F401
from .sweep import (ALPHA, BEST_RPM, DEFAULT_SWEEP, DELAY_RANGE, ENDS, ENTRY_KEYS, KINDS,
                    REQUIRED_KEYS, SPEED_CASE, SWEEP_VERSION, SweepError, TOOL, WITH_KINDS,
                    bench_id, bench_value, check_simulator_setting, conditions, declared_defaults,
                    entry_form, is_finite_number, label, load_sweep, nominal_scenario, number_text,
                    resolve, same_value, scenario_text, select)  # noqa: F401
from .runner import (BUILD_FILE, STOP_GRACE_S, built_by, is_complete, is_kept, read_results,
                     run_all, run_campaign_process, run_condition, stop_running)  # noqa: F401
from .verdicts import (CONCLUSIONS, best_speed_not_beaten, best_speed_significantly,
                       compensated_beats_uncompensated, compensated_equals_stationary, conclusions,
                       constant_row, moved_kinds, overall, paired_test, rate, sensitivity_table,
                       success_cell)  # noqa: F401
from .outputs import (CSV_COLUMNS, benches_markdown, conclusions_markdown, csv_rows,
                      design_markdown, group_markdown, shown, tornado, write_outputs)  # noqa: F401
from .command import (DESCRIPTION, campaign_argv, main, parse_args, prepare)  # noqa: F401
