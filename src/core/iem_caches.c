/* The processor's cache sizes as the C library reports them (no Fortran form):
 * src/core/iem_caches.f90 holds its Fortran interface. */
#include <unistd.h>

/* Bytes of a core's second-level cache (glibc's sysconf; 0 where not known). */
long iem_l2_bytes(void)
{
#ifdef _SC_LEVEL2_CACHE_SIZE
    long n = sysconf(_SC_LEVEL2_CACHE_SIZE);
    return n > 0 ? n : 0;
#else
    return 0;
#endif
}
