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

# What linking the two libraries needs: build/libmcf.a (core) and
# build/libmcfapi.a (api).
LIBS_CORE := -lcholmod -lsuitesparseconfig -lm
LIBS_API  := -ldraco -lcjson
