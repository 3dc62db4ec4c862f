/* Give the heap's free memory back to the system (no Fortran form): src/core/iem_heap.f90
 * holds its Fortran interface. */
#include <stdlib.h> /* defines __GLIBC__ where the C library is glibc */
#ifdef __GLIBC__
#include <malloc.h>
#endif

/* Return the free pages of the heap to the system where the C library can (glibc's
 * malloc_trim); elsewhere nothing. Nothing allocated is touched. */
void iem_heap_release(void)
{
#ifdef __GLIBC__
    (void)malloc_trim(0);
#endif
}
