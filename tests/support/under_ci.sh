# Sourced by the suite's shell scripts: the one rule for CI that tests/support/required.hpp spells for C++ — CI is
# set and not "", "0" or "false". Under it a missing tool or data set fails instead of skipping.
under_ci() { [ -n "${CI:-}" ] && [ "${CI}" != 0 ] && [ "${CI}" != false ]; }
