/* A hint to the processor to bring memory into its caches ahead of use (no Fortran form):
 * src/core/iem_prefetch.f90 holds its Fortran interface. */

/* Ask for the n doubles from p to be brought into the caches, for reading (write = 0) or
 * for writing (write = 1); nothing else happens, whatever p's contents. */
void iem_cache_prefetch(const double *p, int n, int write)
{
    int i;
    if (write) {
        for (i = 0; i < n; i += 8) __builtin_prefetch(p + i, 1, 3);
        __builtin_prefetch(p + n - 1, 1, 3);
    } else {
        for (i = 0; i < n; i += 8) __builtin_prefetch(p + i, 0, 3);
        __builtin_prefetch(p + n - 1, 0, 3);
    }
}
