# Sourced by the install and build scripts: `stage "what" command...` prints one line, sends the
# command's output to $log, and prints that log in full only when the command fails.
stage() {
  local what="$1"
  shift
  echo "$what"
  if ! "$@" >> "$log" 2>&1; then
    echo "failed: $what; the full output ($log):"
    cat "$log"
    exit 1
  fi
}
