# Sourced (not run) by setup.sh, main.sh and test.sh, from the checkout's
# root: the Python they install into and run in, exported as $PYTHON.
#
#   $PYTHON set           that interpreter (the caller's choice);
#   a venv active         its python ($VIRTUAL_ENV);
#   neither               the checkout's own virtual environment,
#                         $CLOCKWORK_VENV or .venv, created here when missing
#                         and put first on PATH for the commands that follow.
#
# So packages never go into the system's Python: a newcomer's clone keeps
# everything in .venv (rm -rf .venv undoes it). As root on a machine whose
# python3 lacks the venv module (Debian's python3-venv), it is installed
# with apt-get, as setup.sh installs libtbb12.

_cw_python_ok() {
  "$1" -c 'import sys; sys.exit(sys.version_info < (3, 11))' 2> /dev/null
}

if [ -n "${PYTHON:-}" ]; then
  :
elif [ -n "${VIRTUAL_ENV:-}" ] && [ -x "$VIRTUAL_ENV/bin/python" ]; then
  PYTHON="$VIRTUAL_ENV/bin/python"
else
  _cw_venv=${CLOCKWORK_VENV:-.venv}
  if [ ! -x "$_cw_venv/bin/python" ]; then
    _cw_base=$(command -v python3.11 || command -v python3 || true)
    if [ -z "$_cw_base" ] || ! _cw_python_ok "$_cw_base"; then
      echo "setup: no Python 3.11 or later (python3.11 or python3) on PATH" >&2
      exit 1
    fi
    if ! "$_cw_base" -m venv "$_cw_venv" > /dev/null 2>&1; then
      rm -rf "$_cw_venv"
      _cw_pkg="python3-venv python$("$_cw_base" -c 'import sys; print("%d.%d" % sys.version_info[:2])')-venv"
      if [ "$(id -u)" -eq 0 ] && command -v apt-get > /dev/null; then
        # shellcheck disable=SC2086
        { apt-get update -qq && apt-get install -y -qq $_cw_pkg > /dev/null; } || true
      fi
      if ! "$_cw_base" -m venv "$_cw_venv" > /dev/null 2>&1; then
        rm -rf "$_cw_venv"
        echo "setup: $_cw_base cannot create a virtual environment in $_cw_venv: install its venv module" \
             "(Debian: apt-get install ${_cw_pkg% *}), or activate a virtual environment of your own" >&2
        exit 1
      fi
    fi
    echo "setup: created the virtual environment $_cw_venv: clockwork and its packages go there" \
         "(source $_cw_venv/bin/activate to use it)"
  fi
  VIRTUAL_ENV=$(cd "$_cw_venv" && pwd)
  PYTHON="$VIRTUAL_ENV/bin/python"
  export VIRTUAL_ENV
fi
case "$PYTHON" in
  */*) ;;
  *) PYTHON=$(command -v "$PYTHON" || echo "$PYTHON") ;;
esac
if ! _cw_python_ok "$PYTHON"; then
  echo "setup: $PYTHON is not Python 3.11 or later" >&2
  exit 1
fi
# The interpreter's own bin folder first: the clockwork command, cmake and
# ninja that pip installs there.
PATH="$(dirname "$PYTHON"):$PATH"
export PYTHON PATH
