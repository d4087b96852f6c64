/* C++ view of the metacell library headers (they are plain C99 without extern "C"). */
#ifndef CELL_METACELL_H
#define CELL_METACELL_H

#ifdef __cplusplus
extern "C" {
#endif
#include "mc_cell.h"
#include "../common/mc_ident.h"
#ifdef __cplusplus
}
#endif

#endif /* CELL_METACELL_H */
