/* IEM_HINT: a cache hint for the memory `bytes` past p, to be read (rw 0) or written (rw 1);
 * no value is read or changed. The address is formed as an integer, since it may lie past
 * the end of the array p points into (the next chunk's data, or nothing). */
#ifndef IEM_CACHE_HINT_H
#define IEM_CACHE_HINT_H
#include <stdint.h>

#define IEM_HINT(p, bytes, rw) \
  __builtin_prefetch((const void *)((uintptr_t)(p) + (uintptr_t)(bytes)), rw, 3)
#endif
