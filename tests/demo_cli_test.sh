#!/usr/bin/env bash
# The demo program as a user meets it: wrong arguments get a clear message and a non-zero exit;
# a short tour writes its logs, plots and pictures. Usage: demo_cli_test.sh DEMO SOURCE_DIR
set -uo pipefail
demo=$(readlink -f "$1")  # absolute: some runs change directory
source_dir=$2
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
failures=0

# expect_error "message part" args...: non-zero exit and the message on stderr.
expect_error() {
  local part=$1
  shift
  if "$demo" "$@" >"$scratch/out" 2>"$scratch/err"; then
    echo "FAIL: '$*' succeeded"; failures=$((failures + 1)); return
  fi
  if ! grep -qF -- "$part" "$scratch/err"; then
    echo "FAIL: '$*' did not say '$part':"; cat "$scratch/err"; failures=$((failures + 1))
  fi
}

expect_error "unknown argument '--bogus' (valid: --robot, " --bogus
expect_error "not built in" --robot ur5
expect_error "--urdf '/no/such.urdf': no such file" --urdf /no/such.urdf --base-link a --tip-link b
expect_error "--urdf needs --base-link and --tip-link" --urdf "$source_dir/models/panda/panda.urdf"
expect_error "--mjcf needs --urdf" --mjcf "$source_dir/models/panda/panda.xml"
expect_error "unknown scenario 'nope' (valid: hold, compliance, " --scenario nope
expect_error "--out needs a value" --out
printf 'stiffness:\n  translation: -5\n' >"$scratch/bad.yaml"
expect_error "bad.yaml:2: stiffness.translation = -5 N/m is outside [0, 100000]" --config "$scratch/bad.yaml"
printf 'nullspace:\n  stiffness: [10, 10, 10]\n' >"$scratch/three.yaml"
expect_error "three.yaml' for 7 joints: nullspace.stiffness" --config "$scratch/three.yaml"
expect_error "--start-q '1,2' has 2 values; the robot has 7 joints" --start-q 1,2
expect_error "--start-q '0,x,0,0,0,0,0': 'x' is not a number" --start-q 0,x,0,0,0,0,0
expect_error "the start configuration is outside the joint range (joint panda_joint4 is at 0" \
  --urdf "$source_dir/models/panda/panda.urdf" --base-link panda_link0 --tip-link panda_link8 \
  --start-q 0,0,0,0,0,0,0
# A URDF alone, without --start-q: the demo chooses a start (q = 0 is outside the Panda's joint 4
# range and singular), says which, and has no warning about it.
"$demo" --urdf "$source_dir/models/panda/panda.urdf" --base-link panda_link0 \
  --tip-link panda_link8 --scenario hold --no-render --no-plots --out "$scratch/chosen" \
  >"$scratch/chosen.log" 2>&1
{ grep -q "^Start configuration (chosen: smallest singular value .*): q = \[" "$scratch/chosen.log" &&
  ! grep -q "Warning: start configuration" "$scratch/chosen.log"; } ||
  { echo "FAIL: a URDF without --start-q:"; cat "$scratch/chosen.log"; failures=$((failures + 1)); }
expect_error "--urdf: " --urdf "$source_dir/models/panda/panda.urdf" --base-link panda_link0 --tip-link gripper
expect_error "--engine: engine 'bullet' is not known; the engines are: mujoco, dart (or both)" --engine bullet
expect_error "--plant: plant 'noisy' is not known (valid: nominal, realistic)" --plant noisy
expect_error "--plant-seed '-3' is not a whole number >= 0" --plant realistic --plant-seed -3
# An MJCF that does not simulate the URDF's joints is a bad argument (exit 2), as in the ROS 2 node.
expect_error "--mjcf: SimulationOptions.joint_names[0] = 'panda_joint1' is not a joint of MJCF" \
  --urdf "$source_dir/models/panda/panda.urdf" --base-link panda_link0 --tip-link panda_link8 \
  --mjcf "$source_dir/models/iiwa14/iiwa14.xml"

# Both engines side by side (where this build has DART): a table with a column per engine.
if "$demo" --robot panda --engine both --scenario hold --no-render --no-plots \
  --out "$scratch/engines" >"$scratch/engines.log" 2>&1; then
  grep -q "Theory, MuJoCo and DART side by side" "$scratch/engines.log" &&
    [ -s "$scratch/engines/mujoco/summary.csv" ] && [ -s "$scratch/engines/dart/summary.csv" ] &&
    grep -q '^"hold","sag under an unknown 1 kg payload (m g / K)","mm",.*,yes,.*,yes$' \
      "$scratch/engines/engines.csv" ||
    { echo "FAIL: --engine both:"; cat "$scratch/engines.log"; failures=$((failures + 1)); }
elif ! grep -q "engine 'dart' is not available" "$scratch/engines.log"; then
  echo "FAIL: --engine both failed:"; cat "$scratch/engines.log"; failures=$((failures + 1))
fi

# A flange the simulation lacks is a bad argument too, found before any scenario runs (exit 2; a
# scenario that then cannot run is its own verdict, exit 3, as an unwritable log below shows).
expect_error "the simulation of --urdf: body 'no_such_flange' not found in model 'panda'" \
  --urdf "$source_dir/models/panda/panda.urdf" --base-link panda_link0 --tip-link panda_link8 \
  --start-q 0,-0.785,0,-2.356,0,1.571,0.785 --flange no_such_flange
"$demo" --help | grep -q "Usage: cartesian_impedance_demo" || { echo "FAIL: --help"; failures=$((failures + 1)); }

# The output folder reaches the plot script as an argument, never through a shell: a quote in its
# name neither runs a command nor loses the plots.
for out in "a'; touch injected; echo '" "robot's data"; do
  (cd "$scratch" && "$demo" --scenario hold --no-render --out "$out") >"$scratch/quoted.log" 2>&1 ||
    { echo "FAIL: --out \"$out\" did not succeed:"; cat "$scratch/quoted.log"; failures=$((failures + 1)); }
  [ -s "$scratch/$out/hold_torques.png" ] ||
    { echo "FAIL: no plots in '$out':"; cat "$scratch/quoted.log"; failures=$((failures + 1)); }
done
[ ! -e "$scratch/injected" ] || { echo "FAIL: a command in --out was run"; failures=$((failures + 1)); }

# An output folder that takes no files is a bad argument, found before anything runs (exit 2):
# /proc/self exists as a folder, but not even root can create files in it; /etc/hostname is a file.
for out in /proc/self /etc/hostname/sub; do
  "$demo" --scenario hold --no-render --no-plots --out "$out" >"$scratch/out" 2>"$scratch/err"
  status=$?
  if [ "$status" -ne 2 ] || ! grep -qF -- "--out '$out': " "$scratch/err" ||
    grep -q "Cartesian impedance demo:" "$scratch/out"; then
    echo "FAIL: --out $out gave exit $status:"; cat "$scratch/out" "$scratch/err"
    failures=$((failures + 1))
  fi
done
# A file that cannot be written during the run (here: a folder stands where hold.csv goes) is
# named, and the run is not a success (exit 3), though its measurements agree.
mkdir -p "$scratch/busy/hold.csv"
"$demo" --scenario hold --no-render --no-plots --out "$scratch/busy" >"$scratch/busy.log" 2>&1
status=$?
if [ "$status" -ne 3 ] ||
  ! grep -qF "Not written: output file '$scratch/busy/hold.csv' cannot be created" "$scratch/busy.log" ||
  grep -q "Every measurement agrees" "$scratch/busy.log"; then
  echo "FAIL: an unwritable log gave exit $status:"; cat "$scratch/busy.log"; failures=$((failures + 1))
fi

# A short tour on the iiwa14, with plots and (where EGL works) pictures.
if ! "$demo" --robot iiwa14 --scenario hold --scenario wrench --out "$scratch/tour" >"$scratch/tour.log" 2>&1; then
  echo "FAIL: the tour did not succeed:"; cat "$scratch/tour.log"; failures=$((failures + 1))
fi
for file in summary.csv hold.csv wrench.csv wrench_force.png wrench_pose_error.png hold_torques.png; do
  [ -s "$scratch/tour/$file" ] || { echo "FAIL: $file was not written"; failures=$((failures + 1)); }
done
grep -q "contact force under a commanded 10 N" "$scratch/tour/summary.csv" ||
  { echo "FAIL: summary.csv lacks the wrench line"; failures=$((failures + 1)); }
if ! grep -q "no pictures" "$scratch/tour.log"; then
  [ -s "$scratch/tour/wrench_pressing_on_the_table.png" ] ||
    { echo "FAIL: no picture although rendering is available"; failures=$((failures + 1)); }
fi
grep -q "Every measurement agrees with theory" "$scratch/tour.log" ||
  { echo "FAIL: the tour's checks did not all pass:"; cat "$scratch/tour.log"; failures=$((failures + 1)); }

[ "$failures" -eq 0 ] && echo "demo CLI: all checks passed"
exit "$failures"
