#!/usr/bin/env bash
# The Slurm job-array recipe of doc/experiments.md ("Beyond one machine: shards"), run for real
# on a one-node Slurm cluster on loopback, and checked against a single run of the same design.
#
#   1. installs slurm-wlm and munge with apt-get when they are missing;
#   2. starts munged, slurmctld and slurmd (node "localhost", 127.0.0.1, the machine's real CPU
#      topology and memory) in a temporary directory of its own, with its own munge key, ports,
#      slurm.conf (SLURM_CONF), state, spool, logs and pid files;
#   3. takes that page's job script as it is written there, with a small design put in place of
#      the page's (--case all --rpm 12000 --trials 4 --seed 7 --jobs 1) and submits it as a
#      3-task array (sbatch --array=1-3 --cpus-per-task=1 --wait);
#   4. runs the page's campaign_merge line as a job depending on the array
#      (sbatch --dependency=afterok:<array job> --wait);
#   5. runs the same design once as a single run (no Slurm) and compares: every shard holds its
#      slice of the design, the merged trials.csv equals the single run's apart from wall time
#      (wall_s), report.md, Table II and every trace are the same, and so is summary.json
#      (apart from paths and timing);
#   6. on exit (success or not) cancels its jobs, stops slurmd, slurmctld and munged, checks that
#      none of its processes is left and removes the temporary directory.
#
# Needs root (apt-get, the Slurm daemons). Uses the workspace's devel space: $PEDICLE_DRILLING_SETUP
# (a setup.bash), else $PEDICLE_DRILLING_BIN_DIR/../../setup.bash, else
# catkin_ws/devel/setup.bash of this checkout. SLURM_CAMPAIGN_KEEP=1 keeps the temporary directory.
# Exit status 0 when the merged shards and the single run agree.
set -euo pipefail
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:${PATH}"

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "${HERE}/../.." && pwd)"
DOC="${ROOT}/doc/experiments.md"
SHARDS=3
DESIGN_CASE=all
DESIGN_RPM=12000
DESIGN_TRIALS=4
DESIGN_SEED=7
DESIGN_JOBS=1
JOB_TIMEOUT_S=600  # a bound on each sbatch --wait: a job that cannot start stays queued

# Long commands run as children waited for by the `wait` builtin: SIGINT/SIGTERM then reach the
# trap (cleanup) at once instead of after the command.
BACKGROUND_PID=""
in_background() {
  local status=0
  "$@" &
  BACKGROUND_PID=$!
  wait "${BACKGROUND_PID}" || status=$?
  BACKGROUND_PID=""  # reaped: its id may be reused
  return ${status}
}
log() { printf 'slurm_campaign: %s\n' "$*" >&2; }
die() { log "FAILED: $*"; exit 1; }

# ---------------------------------------------------------------- packages
need_install=()
for package in slurm-wlm munge; do
  if ! dpkg-query -W -f='${Status}' "${package}" 2>/dev/null | grep -q 'install ok installed'; then
    need_install+=("${package}")
  fi
done
if [ ${#need_install[@]} -gt 0 ]; then
  [ "$(id -u)" -eq 0 ] || die "missing packages ${need_install[*]} and not root to install them"
  log "installing ${need_install[*]}"
  export DEBIAN_FRONTEND=noninteractive
  # The packages' init scripts must not start system-wide daemons: without a policy-rc.d, put a
  # temporary one in place for the install (removed right after).
  policy_added=""
  if [ ! -e /usr/sbin/policy-rc.d ]; then
    trap 'rm -f /usr/sbin/policy-rc.d' EXIT
    printf '#!/bin/sh\nexit 101\n' > /usr/sbin/policy-rc.d
    chmod 755 /usr/sbin/policy-rc.d
    policy_added=1
  fi
  install_status=0
  { apt-get update -qq && apt-get install -y -qq --no-install-recommends "${need_install[@]}" \
      > /dev/null; } || install_status=$?
  if [ -n "${policy_added}" ]; then rm -f /usr/sbin/policy-rc.d; trap - EXIT; fi
  [ ${install_status} -eq 0 ] || die "apt-get install ${need_install[*]} exited ${install_status}"
fi
for tool in munged munge unmunge slurmctld slurmd sbatch scontrol squeue sinfo scancel; do
  command -v "${tool}" > /dev/null || die "${tool} not found after installing slurm-wlm munge"
done
[ "$(id -u)" -eq 0 ] || die "the Slurm daemons of this test run as root; run it as root"

# ---------------------------------------------------------------- workspace
SETUP="${PEDICLE_DRILLING_SETUP:-}"
if [ -z "${SETUP}" ] && [ -n "${PEDICLE_DRILLING_BIN_DIR:-}" ]; then
  SETUP="${PEDICLE_DRILLING_BIN_DIR}/../../setup.bash"
fi
SETUP="${SETUP:-${ROOT}/catkin_ws/devel/setup.bash}"
[ -f "${SETUP}" ] || die "no devel space: ${SETUP} (build the workspace first: make build)"
SETUP_DIR="$(cd "$(dirname "${SETUP}")" && pwd)"
# setup.bash reads unset variables: source it without `set -u`.
set +u
# shellcheck disable=SC1090,SC1091
source "${SETUP_DIR}/setup.bash"
set -u
rospack find pedicle_drilling > /dev/null || die "rospack does not find pedicle_drilling"

# ---------------------------------------------------------------- the cluster's directory
# slurmstepd makes a Unix socket <SlurmdSpoolDir>/localhost_<job>.<step> (step up to 10 digits),
# and a socket path has at most 107 characters; a job whose socket cannot be made is neither run
# nor failed (it stays queued). With a TMPDIR too deep for that, the cluster lives in /tmp.
PARENT="${TMPDIR:-/tmp}"
if [ $(( ${#PARENT} + 22 + 17 + 10 + 1 + 10 )) -gt 107 ]; then
  log "TMPDIR is too deep for the daemons' Unix sockets: the cluster directory goes to /tmp"
  PARENT=/tmp
fi
W="$(mktemp -d "${PARENT}/slurm_campaign.XXXXXX")"
log "cluster directory ${W}"
# Every process this test starts (daemons, job steps, job processes) carries this variable:
# the cleanup finds any of them still running by it, and by nothing else.
MARK="PD_SLURM_CAMPAIGN_RUN=${W}"
MUNGED_PID=""
SLURMCTLD_PID=""
SLURMD_PID=""

pid_alive() {  # a process that has not exited (a zombie counts as exited)
  local stat state
  { read -r stat < "/proc/$1/stat"; } 2> /dev/null || return 1
  state="${stat##*) }"  # the state follows the command name, which may hold spaces
  state="${state%% *}"
  [ -n "${state}" ] && [ "${state}" != Z ]
}

stop_pid() {  # SIGTERM, up to 30 s for the exit, then SIGKILL; reaps it when it is our child
  local pid="$1" name="$2" i
  [ -n "${pid}" ] || return 0
  if pid_alive "${pid}"; then
    kill -TERM "${pid}" 2>/dev/null || true
    for i in $(seq 300); do
      pid_alive "${pid}" || break
      sleep 0.1
    done
    if pid_alive "${pid}"; then
      log "${name} (pid ${pid}) ignored SIGTERM for 30 s: SIGKILL"
      kill -KILL "${pid}" 2>/dev/null || true
    fi
  fi
  wait "${pid}" 2>/dev/null || true
}

marked_pids() {  # processes whose environment holds ${MARK}
  local entry pid
  for entry in /proc/[0-9]*; do
    pid="${entry#/proc/}"
    [ "${pid}" != "$$" ] && [ "${pid}" != "${BASHPID}" ] || continue
    pid_alive "${pid}" || continue
    if { tr '\0' '\n' < "${entry}/environ"; } 2> /dev/null | grep -qxF "${MARK}"; then
      echo "${pid}"
    fi
  done
}

show_logs() {
  local file
  for file in "${W}"/log/*.log "${W}"/submit/*.out; do
    [ -f "${file}" ] || continue
    log "---- last lines of ${file#"${W}"/}"
    tail -n 25 "${file}" >&2 || true
  done
}

cleanup() {
  local status=$? i jobs left
  set +e
  trap - EXIT INT TERM
  if [ ${status} -ne 0 ] && [ -d "${W}" ]; then show_logs; fi
  stop_pid "${BACKGROUND_PID}" "$(ps -o comm= -p "${BACKGROUND_PID:-0}" 2> /dev/null)"
  if [ -n "${SLURMCTLD_PID}" ] && pid_alive "${SLURMCTLD_PID}"; then
    # Every job of this private cluster: slurmd ends their steps and processes on scancel, and
    # squeue lists a job until that is done (bounded).
    jobs="$(squeue -h -o %A 2> /dev/null | sort -u)"
    if [ -n "${jobs}" ]; then
      log "cancelling jobs $(echo ${jobs})"
      scancel ${jobs}
      for i in $(seq 120); do
        [ -z "$(squeue -h -o %A 2> /dev/null)" ] && break
        sleep 0.5
      done
    fi
  fi
  stop_pid "${SLURMD_PID}" slurmd
  stop_pid "${SLURMCTLD_PID}" slurmctld
  stop_pid "${MUNGED_PID}" munged
  left="$(marked_pids)"
  if [ -n "${left}" ]; then
    log "processes of this test still running after the daemons stopped: $(echo ${left})"
    kill -TERM ${left} 2> /dev/null
    for i in $(seq 100); do
      [ -z "$(marked_pids)" ] && break
      sleep 0.1
    done
    left="$(marked_pids)"
    if [ -n "${left}" ]; then kill -KILL ${left} 2> /dev/null; fi
    wait 2> /dev/null  # reap those that were children of this script
    [ ${status} -ne 0 ] || status=1
  fi
  if [ "${SLURM_CAMPAIGN_KEEP:-0}" = 1 ]; then
    log "kept ${W}"
  else
    rm -rf "${W}"
  fi
  if [ ${status} -eq 0 ]; then log "cluster stopped, nothing left running"; fi
  exit ${status}
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

mkdir -p "${W}/munge" "${W}/state" "${W}/spool" "${W}/log" "${W}/run" "${W}/submit"
chmod 711 "${W}" "${W}/munge"  # munged wants its socket's directory searchable by all

free_port() {
  /usr/bin/python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

# ---------------------------------------------------------------- munged
MUNGE_SOCKET="${W}/munge/munge.socket"
if command -v mungekey > /dev/null; then
  mungekey --create --keyfile="${W}/munge/munge.key" 2> /dev/null
else
  dd if=/dev/urandom of="${W}/munge/munge.key" bs=1024 count=1 status=none
fi
chmod 400 "${W}/munge/munge.key"
env "${MARK}" munged --foreground --force --socket="${MUNGE_SOCKET}" \
  --key-file="${W}/munge/munge.key" --pid-file="${W}/munge/munged.pid" \
  --log-file="${W}/log/munged.log" --seed-file="${W}/munge/munged.seed" \
  > "${W}/log/munged.out.log" 2>&1 &
MUNGED_PID=$!
ready=""
for i in $(seq 50); do
  if munge -n -S "${MUNGE_SOCKET}" 2> /dev/null | unmunge -S "${MUNGE_SOCKET}" > /dev/null 2>&1
  then ready=1; break; fi
  pid_alive "${MUNGED_PID}" || break
  sleep 0.2
done
[ -n "${ready}" ] || die "munged did not come up (see log/munged.log)"
log "munged up (pid ${MUNGED_PID})"

# ---------------------------------------------------------------- slurm.conf
# The node as slurmd sees it (sockets, cores, threads, memory), so that the configuration matches
# the machine; fall back to nproc and /proc/meminfo.
HW="$(slurmd -C 2> /dev/null | grep -m1 '^NodeName=' || true)"
NODE_HW=""
for key in CPUs Boards SocketsPerBoard CoresPerSocket ThreadsPerCore RealMemory; do
  value="$(printf '%s\n' "${HW}" | tr ' ' '\n' | sed -n "s/^${key}=//p")"
  if [ -n "${value}" ]; then NODE_HW="${NODE_HW} ${key}=${value}"; fi
done
if ! printf '%s' "${NODE_HW}" | grep -q 'CPUs='; then
  NODE_HW=" CPUs=$(nproc) RealMemory=$(awk '/^MemTotal:/ {print int($2 / 1024)}' /proc/meminfo)"
fi
CTLD_PORT="$(free_port)"
SLURMD_PORT="$(free_port)"
while [ "${SLURMD_PORT}" = "${CTLD_PORT}" ]; do SLURMD_PORT="$(free_port)"; done
export SLURM_CONF="${W}/slurm.conf"
cat > "${SLURM_CONF}" <<EOF
# One-node cluster of test/slurm/slurm_campaign.sh, on loopback, everything in ${W}.
ClusterName=pdcampaign
SlurmctldHost=localhost(127.0.0.1)
SlurmctldPort=${CTLD_PORT}
SlurmdPort=${SLURMD_PORT}
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=${MUNGE_SOCKET}
StateSaveLocation=${W}/state
SlurmdSpoolDir=${W}/spool
SlurmctldPidFile=${W}/run/slurmctld.pid
SlurmdPidFile=${W}/run/slurmd.pid
SlurmctldLogFile=${W}/log/slurmctld.log
SlurmdLogFile=${W}/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
MpiDefault=none
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
ReturnToService=2
MailProg=/bin/true
MinJobAge=600
NodeName=localhost NodeAddr=127.0.0.1 NodeHostname=localhost${NODE_HW} State=UNKNOWN
PartitionName=campaign Nodes=localhost Default=YES MaxTime=INFINITE State=UP
EOF
log "slurm.conf: node localhost${NODE_HW}, ports ${CTLD_PORT}/${SLURMD_PORT}"

# ---------------------------------------------------------------- slurmctld, slurmd
env "${MARK}" slurmctld -D -i > "${W}/log/slurmctld.out.log" 2>&1 &
SLURMCTLD_PID=$!
ready=""
for i in $(seq 60); do
  if scontrol ping 2> /dev/null | grep -q 'is UP'; then ready=1; break; fi
  pid_alive "${SLURMCTLD_PID}" || break
  sleep 0.5
done
[ -n "${ready}" ] || die "slurmctld did not answer scontrol ping within 30 s"
env "${MARK}" slurmd -D -N localhost > "${W}/log/slurmd.out.log" 2>&1 &
SLURMD_PID=$!
state=""
for i in $(seq 60); do
  state="$(sinfo -h -N -n localhost -o %T 2> /dev/null | head -n1)"
  [ "${state}" = idle ] && break
  pid_alive "${SLURMD_PID}" || break
  sleep 0.5
done
[ "${state}" = idle ] || die "node localhost is '${state:-unknown}', not idle, after 30 s"
log "slurmctld (pid ${SLURMCTLD_PID}) and slurmd (pid ${SLURMD_PID}) up, node localhost idle"

# ---------------------------------------------------------------- the documented job script
[ -f "${DOC}" ] || die "no doc/experiments.md beside the test: ${DOC}"
SECTION="$(awk '/^##+ Beyond one machine: shards/ {on = 1; next} on && /^##+ / {exit} on' \
  "${DOC}")"
JOB_SCRIPT="$(printf '%s\n' "${SECTION}" \
  | awk '/^```sh$/ && !done {on = 1; next} on && /^```$/ {on = 0; done = 1} on')"
MERGE_COMMAND="$(printf '%s\n' "${SECTION}" \
  | grep -o "rosrun pedicle_drilling campaign_merge [^'\"\`]*" | head -n1 | sed 's/ *$//')"
[ -n "${JOB_SCRIPT}" ] || die "doc/experiments.md: no \`\`\`sh job script in 'Beyond one machine: shards'"
[ -n "${MERGE_COMMAND}" ] || die "doc/experiments.md: no campaign_merge command in 'Beyond one machine: shards'"
# The design is the only thing replaced: the documented one is too big for a test.
JOB_SCRIPT_SMALL="${JOB_SCRIPT}"
for option in "--case ${DESIGN_CASE}" "--rpm ${DESIGN_RPM}" "--trials ${DESIGN_TRIALS}" \
    "--seed ${DESIGN_SEED}" "--jobs ${DESIGN_JOBS}"; do
  name="${option%% *}"
  count="$(printf '%s\n' "${JOB_SCRIPT_SMALL}" | grep -o -- "${name} [^ ]*" | wc -l)"
  [ "${count}" -le 1 ] || die "documented job script: ${name} given ${count} times"
  if [ "${count}" -eq 1 ]; then
    JOB_SCRIPT_SMALL="$(printf '%s\n' "${JOB_SCRIPT_SMALL}" | sed "s|${name} [^ ]*|${option}|")"
  elif [ "${name}" != --case ]; then
    die "documented job script: no ${name} option to replace"
  fi
done
printf '%s\n' "${JOB_SCRIPT_SMALL}" > "${W}/submit/campaign_array.sh"
chmod 755 "${W}/submit/campaign_array.sh"
# The documented script sources catkin_ws/devel/setup.bash relative to the submit directory.
mkdir -p "${W}/submit/catkin_ws"
ln -s "${SETUP_DIR}" "${W}/submit/catkin_ws/devel"
log "job script (doc/experiments.md's, with this test's design), submitted with --array=1-${SHARDS}" \
  "--cpus-per-task=1 (sbatch options override the script's #SBATCH lines):"
sed 's/^/    /' "${W}/submit/campaign_array.sh" >&2

# ---------------------------------------------------------------- submit the array, then the merge
cd "${W}/submit"
start=$(date +%s)
array_status=0
in_background env "${MARK}" timeout "${JOB_TIMEOUT_S}" sbatch --parsable --wait --array="1-${SHARDS}" \
  --cpus-per-task=1 --job-name=campaign_shards --output='slurm-%A_%a.out' \
  campaign_array.sh > array.jobid || array_status=$?
ARRAY_ID="$(cut -d';' -f1 array.jobid)"
[ -n "${ARRAY_ID}" ] || die "sbatch printed no job id (exit ${array_status})"
[ ${array_status} -eq 0 ] || die "array job ${ARRAY_ID}: sbatch --wait exited ${array_status}"
log "array job ${ARRAY_ID} (${SHARDS} tasks) done in $(( $(date +%s) - start )) s"
for k in $(seq "${SHARDS}"); do
  tail -n 1 "slurm-${ARRAY_ID}_${k}.out" | tr '\r' '\n' | tail -n 1 | sed "s/^/    task ${k}: /" >&2
done

merge_status=0
in_background env "${MARK}" timeout "${JOB_TIMEOUT_S}" sbatch --parsable --wait \
  --dependency="afterok:${ARRAY_ID}" --kill-on-invalid-dep=yes \
  --job-name=campaign_merge --output='merge-%j.out' --wrap="${MERGE_COMMAND}" > merge.jobid || merge_status=$?
MERGE_ID="$(cut -d';' -f1 merge.jobid)"
[ -n "${MERGE_ID}" ] || die "sbatch (merge) printed no job id (exit ${merge_status})"
[ ${merge_status} -eq 0 ] || die "merge job ${MERGE_ID} ('${MERGE_COMMAND}') exited ${merge_status}"
sed 's/^/    merge: /' "merge-${MERGE_ID}.out" >&2

# ---------------------------------------------------------------- the same design, one run
log "single run of the same design"
in_background rosrun pedicle_drilling campaign --case "${DESIGN_CASE}" --rpm "${DESIGN_RPM}" \
  --trials "${DESIGN_TRIALS}" --seed "${DESIGN_SEED}" --jobs "${DESIGN_JOBS}" \
  --out "${W}/single" > "${W}/single.log" 2>&1 || die "single run failed: $(tail -n 5 "${W}/single.log")"

# ---------------------------------------------------------------- compare
/usr/bin/python3 - "${W}/submit/shards" "${W}/submit/merged" "${W}/single" "${SHARDS}" <<'PY'
import csv
import json
import math
import os
import re
import sys

shards_dir, merged, single, count = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
# Wall-clock columns of trials.csv (pd_campaign/report.py TRIAL_COLUMNS): the only ones that may
# differ between two runs of the same design.
WALL_COLUMNS = ('wall_s',)
# Keys of summary.json that would hold timing or paths (none today): ignored if they appear.
IGNORED_KEY = re.compile(r'wall|elapsed|path|_dir$')
failures = []


def check(condition, message):
    if not condition:
        failures.append(message)
    return condition


def rows(path):
    with open(path, newline='') as handle:
        reader = csv.DictReader(handle)
        header = [c for c in reader.fieldnames if c not in WALL_COLUMNS]
        return header, [{k: v for k, v in r.items() if k not in WALL_COLUMNS} for r in reader]


def without_ignored(value):
    if isinstance(value, dict):
        return {k: without_ignored(v) for k, v in value.items() if not IGNORED_KEY.search(k)}
    if isinstance(value, list):
        return [without_ignored(v) for v in value]
    return value


# summary.json: identical, medians included (a single run summarises its rows as trials.csv
# keeps them, as campaign_merge does).


def compare_summary(merged_value, single_value, where):
    if isinstance(single_value, dict) and isinstance(merged_value, dict):
        if check(sorted(merged_value) == sorted(single_value), '%s: keys differ' % where):
            for key in single_value:
                compare_summary(merged_value[key], single_value[key], '%s/%s' % (where, key))
    elif isinstance(single_value, list) and isinstance(merged_value, list):
        if check(len(merged_value) == len(single_value), '%s: lengths differ' % where):
            for i, (a, b) in enumerate(zip(merged_value, single_value)):
                compare_summary(a, b, '%s[%d]' % (where, i))
    else:
        check(merged_value == single_value,
              '%s: %r (merged) != %r (single)' % (where, merged_value, single_value))


def read(path, mode='r'):
    with open(path, mode) as handle:
        return handle.read()


single_header, single_rows = rows(os.path.join(single, 'trials.csv'))
with open(os.path.join(single, 'design.json')) as handle:
    design_size = json.load(handle)['meta']['design_size']
check(len(single_rows) == design_size, 'single run: %d rows, design of %d'
      % (len(single_rows), design_size))
check(all(r['error'] == '' for r in single_rows), 'single run: trials with errors')
canonical = [r['trial_id'] for r in single_rows]  # trials.csv is in the design's order

seen = []
for k in range(1, count + 1):
    directory = os.path.join(shards_dir, str(k))
    with open(os.path.join(directory, 'design.json')) as handle:
        shard = json.load(handle)['shard']
    check(shard == '%d/%d' % (k, count), 'shards/%d ran shard %s, not %d/%d'
          % (k, shard, k, count))
    ids = [r['trial_id'] for r in rows(os.path.join(directory, 'trials.csv'))[1]]
    check(ids == canonical[k - 1::count], 'shards/%d holds %s, not its slice %s'
          % (k, ids, canonical[k - 1::count]))
    seen += ids
check(sorted(seen) == sorted(canonical), 'the shards do not partition the design')

merged_header, merged_rows = rows(os.path.join(merged, 'trials.csv'))
check(merged_header == single_header, 'trials.csv columns differ')
if check(len(merged_rows) == len(single_rows), 'merged %d rows, single %d'
         % (len(merged_rows), len(single_rows))):
    for a, b in zip(merged_rows, single_rows):
        diff = sorted(c for c in single_header if a.get(c) != b.get(c))
        check(not diff, 'trial %s differs in %s' % (b['trial_id'], ', '.join(diff)))
summaries = [without_ignored(json.loads(read(os.path.join(d, 'summary.json'))))
             for d in (merged, single)]
compare_summary(summaries[0], summaries[1], 'summary.json')
for name in ('report.md', 'table2.md', 'table2.csv'):
    check(read(os.path.join(merged, name)) == read(os.path.join(single, name)),
          '%s differs' % name)
traces = [sorted(os.listdir(os.path.join(d, 'traces'))) for d in (merged, single)]
if check(traces[0] == traces[1], 'different trace files'):
    for name in traces[1]:
        check(read(os.path.join(merged, 'traces', name), 'rb') ==
              read(os.path.join(single, 'traces', name), 'rb'), 'trace %s differs' % name)

if failures:
    print('slurm_campaign: merged shards and single run DIFFER:\n  ' + '\n  '.join(failures))
    sys.exit(1)
groups = summaries[1]['groups']
print('slurm_campaign: OK: %d shards of %d trials merged = the single run: trials.csv (apart '
      'from %s), report.md, Table II, %d traces, summary.json; Table III: %s'
      % (count, len(canonical), ', '.join(WALL_COLUMNS), len(traces[1]),
         ', '.join('%s %d/%d' % (g['case'], g['successes'], g['trials']) for g in groups)))
PY
