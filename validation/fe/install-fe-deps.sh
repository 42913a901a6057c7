#!/bin/sh
# Dependencies of the finite-element reference curves (validation/fe/run_references.py).
# Not part of CI: CI does not run CalculiX.  Debian 12: CalculiX ccx 2.20.
set -e
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO=sudo
$SUDO apt-get update
$SUDO apt-get install -y calculix-ccx python3
