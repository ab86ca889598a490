# SPDX-License-Identifier: MIT
"""Generated from api/mcfd.proto by clients/python/gen_stubs.sh (make python-stubs): do not edit."""
