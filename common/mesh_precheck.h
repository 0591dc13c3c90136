/* mesh_precheck.h: cheap checks of a mesh file before assimp reads it. A
 * PLY header names its element counts, and assimp reserves memory for them
 * before it reads any data: a 200-byte file that promises two billion
 * vertices took memory without bound and never finished. The header's
 * counts are held against the bytes the file has (each element needs at
 * least a byte per property in binary, two in ASCII). Owns the
 * mesh_precheck prefix. */
#ifndef CT_COMMON_MESH_PRECHECK_H
#define CT_COMMON_MESH_PRECHECK_H

#include <stddef.h>
#include <stdio.h>

#include "common/error.h"

/* Reads the start of f (the file path, open at its start, size bytes):
 * CT_OK, or CT_EPARSE naming path and what its header promises beyond its
 * size. Files that are not PLY pass. */
int mesh_precheck(FILE *f, const char *path, size_t size, ct_error *err);

#endif
