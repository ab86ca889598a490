# SPDX-License-Identifier: MIT
# flags.mk - how every C and C++ file of the project is compiled and
# linked: the top-level Makefile and lab/Makefile both include it, so the
# lab's programs build exactly as the product does (WERROR=1, SAN=...,
# OPT=...). The includer sets B (where objects go; BUILD_DIR names it)
# and its own -I flags.

# build/, or build-san/ under sanitizers (make SAN=address,undefined ...)
BUILD_DIR := $(if $(SAN),build-san,build)

CC  ?= cc
CXX ?= c++

WARN := -std=c11 -Wall -Wextra -Wpedantic -Wshadow -Wstrict-prototypes \
        -Wmissing-prototypes -Wformat=2 -Wcast-qual -Wundef
CXXWARN := -std=c++17 -Wall -Wextra -Wshadow -Wformat=2 -Wundef
ifeq ($(WERROR),1)
WARN    += -Werror
CXXWARN += -Werror
endif

OPT      ?= -O2 -g
CFLAGS   ?= $(OPT)
CXXFLAGS ?= $(OPT)
LDFLAGS  ?=
ifdef SAN
CFLAGS   := -O1 -g -fsanitize=$(SAN) -fno-sanitize-recover=all -fno-omit-frame-pointer
CXXFLAGS := $(CFLAGS)
LDFLAGS  += -fsanitize=$(SAN)
endif

# What linking the two libraries needs: $(B)/libmcf.a (core) and
# $(B)/libmcfapi.a (api), in the includer's B (hence `=`, not `:=`).
#
# CHOLMOD without its OpenMP runtime: Debian's libcholmod 3.0.14 opens
# about 150,000 OpenMP parallel regions per factorization of a 435k-vertex
# scan (every supernode, even with one thread: 45% of the factorization).
# $(B)/libcholmod_serial.a (built by the top-level Makefile) is Debian's
# own static libcholmod.a (from libsuitesparse-dev) with its three calls
# into libgomp renamed by objcopy to the serial stand-ins of
# core/cholmod_serial/stand_ins.c, which run a region inline on the
# calling thread (and its clock for BLAS timings to one that reads 0).
# Nothing is interposed process-wide: libgomp is not loaded, other
# libraries keep their own runtime, and each of mcfd's workers runs its
# regions on its own stack (README, Benchmarks).
CHOLMOD_SERIAL = $(B)/libcholmod_serial.a
LIBS_CORE = $(CHOLMOD_SERIAL) -lamd -lcolamd -lccolamd -lcamd -lmetis \
            -llapack -lblas -lsuitesparseconfig -lm -lpthread
LIBS_API  := -ldraco -lcjson
