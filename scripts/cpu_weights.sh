#!/usr/bin/env bash
# CPU weights for two groups of processes: `realtime` at ten times the weight of `others`.
# The kernel's `cpu` controller (cgroup v1, or v2 where the root delegates it) gives each
# group CPU in proportion to its weight while both want more than there is, and gives a
# group whatever the other leaves idle; a process's children stay in its group, whatever
# session or process group they make for themselves.
#
#   scripts/cpu_weights.sh make PID        prints a handle for groups that live as long as
#                                          process PID (the run), or fails where groups
#                                          cannot be made (no write access to the controller)
#   scripts/cpu_weights.sh join H GROUP    moves the calling shell into GROUP (realtime|others)
#   scripts/cpu_weights.sh remove H        moves what is left to the root group, removes both
set -uo pipefail

V1=/sys/fs/cgroup/cpu
V2=/sys/fs/cgroup

# The weights: 10 to 1, in each version's unit.
v1_weight() { [ "$1" = realtime ] && echo 10240 || echo 1024; }
v2_weight() { [ "$1" = realtime ] && echo 1000 || echo 100; }

root_of() { # root_of HANDLE: the hierarchy the handle's groups live in
  case "$1" in v1:*) echo "$V1" ;; v2:*) echo "$V2" ;; esac
}

make_groups() {
  local name version root group
  name=skyhive-test-$1-$(date +%s%N)
  if [ -w "$V1" ] && [ -f "$V1/cpu.shares" ]; then
    version=v1 root=$V1
  elif [ -w "$V2" ] && grep -qw cpu "$V2/cgroup.subtree_control" 2>/dev/null; then
    version=v2 root=$V2
  else
    return 1
  fi
  sweep "$root"
  for group in realtime others; do
    mkdir "$root/$name-$group" 2>/dev/null || { remove_groups "$version:$name"; return 1; }
    if [ $version = v1 ]; then
      v1_weight $group >"$root/$name-$group/cpu.shares"
    else
      v2_weight $group >"$root/$name-$group/cpu.weight"
    fi || { remove_groups "$version:$name"; return 1; }
  done
  echo "$version:$name"
}

sweep() { # sweep ROOT: the empty groups of runs that are gone (their PID is in the name)
  local group pid
  for group in "$1"/skyhive-test-*-*-realtime "$1"/skyhive-test-*-*-others; do
    [ -d "$group" ] || continue
    pid=${group##*/skyhive-test-}; pid=${pid%%-*}
    kill -0 "$pid" 2>/dev/null || rmdir "$group" 2>/dev/null || true
  done
}

join_group() { # join_group HANDLE GROUP: the caller's shell is our parent
  echo "$PPID" >"$(root_of "$1")/${1#*:}-$2/cgroup.procs"
}

remove_groups() {
  local root group pid
  root=$(root_of "$1")
  for group in realtime others; do
    [ -d "$root/${1#*:}-$group" ] || continue
    while read -r pid; do echo "$pid" >"$root/cgroup.procs" 2>/dev/null; done \
      <"$root/${1#*:}-$group/cgroup.procs"
    rmdir "$root/${1#*:}-$group" 2>/dev/null || true
  done
}

case "${1:-}" in
  make) make_groups "$2" ;;
  join) join_group "$2" "$3" ;;
  remove) remove_groups "$2" ;;
  *) echo "usage: $0 make PID | join HANDLE GROUP | remove HANDLE" >&2; exit 2 ;;
esac
