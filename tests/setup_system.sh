#!/usr/bin/env bash
# System packages the test suite needs: headless Chromium for the HTML report check,
# LinuxCNC (linuxcnc-uspace: its rs274 interpreter checks the part programs), and ads-client from
# npm (tests/ads_client: an ADS client we did not write checks the simulated PLC), and PostgreSQL
# (postgresql: the history tests start a throwaway server of their own, tests/pg_server.py), and
# poppler-utils (pdftoppm, pdftotext: the report PDF test turns its pages into images and text).
# Installed here, by the tests' set-up, so a fresh machine needs nothing by hand. The Debian packages
# missing are installed by apt-get after one index update, beside npm; the Makefile runs this beside
# the Python install.
set -u
browser=()      # chromium, installed with its recommended packages (as it always was)
missing=()      # the other Debian packages, installed without theirs
consequence=()  # what each missing one means for the suite, said when it could not be installed
if ! command -v chromium >/dev/null 2>&1; then
  browser+=(chromium chromium-driver); consequence+=("chromium: the browser test will fail")
fi
if ! command -v rs274 >/dev/null 2>&1; then
  missing+=(linuxcnc-uspace); consequence+=("linuxcnc-uspace (rs274, the motion module): its tests skip")
fi
if ! ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1; then
  missing+=(postgresql); consequence+=("postgresql: the PostgreSQL history tests skip")
fi
if ! command -v pdftoppm >/dev/null 2>&1; then
  missing+=(poppler-utils); consequence+=("poppler-utils (pdftoppm, pdftotext): the PDF test will fail")
fi
npm_pid=""
if [ ! -d tests/ads_client/node_modules/ads-client ]; then
  if command -v npm >/dev/null 2>&1; then
    echo "tests/setup_system.sh: installing ads-client (npm) into tests/ads_client"
    ( (cd tests/ads_client && npm ci --no-audit --no-fund) >/dev/null 2>&1 \
      || echo "tests/setup_system.sh: could not install ads-client; the ADS fidelity tests skip" ) &
    npm_pid=$!
  else
    echo "tests/setup_system.sh: npm missing; the ADS fidelity tests skip"
  fi
fi
if [ ${#browser[@]} -gt 0 ] || [ ${#missing[@]} -gt 0 ]; then
  if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
    echo "tests/setup_system.sh: installing ${browser[*]} ${missing[*]} (Debian packages)"
    if ! (apt-get update -qq \
          && { [ ${#browser[@]} -eq 0 ] || DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${browser[@]}"; } \
          && { [ ${#missing[@]} -eq 0 ] || DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
                 --no-install-recommends "${missing[@]}"; }) >/dev/null 2>&1; then
      for said in "${consequence[@]}"; do echo "tests/setup_system.sh: could not install $said"; done
    fi
  else
    for said in "${consequence[@]}"; do echo "tests/setup_system.sh: missing and not root: $said"; done
  fi
fi
if [ -n "$npm_pid" ]; then wait "$npm_pid"; fi
exit 0
