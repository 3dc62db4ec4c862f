/* A hint to the processor to bring memory into its caches ahead of use (no Fortran form),
 * and the size of the cache each CPU may count on: src/core/iem_prefetch.f90 holds their
 * Fortran interfaces. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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

/* The number of CPUs in a Linux CPU list such as "0-3,8,10-11" (0 when it cannot be read). */
static long cpu_count(const char *list)
{
    long n = 0, a, b;
    const char *p = list;
    while (*p) {
        char *end;
        a = strtol(p, &end, 10);
        if (end == p) break;
        b = a;
        p = end;
        if (*p == '-') {
            b = strtol(p + 1, &end, 10);
            if (end == p + 1) break;
            p = end;
        }
        if (b >= a) n += b - a + 1;
        if (*p == ',') p++;
        else break;
    }
    return n;
}

/* The first line of the file at path into buf (size n); 0 when it cannot be read. */
static int read_line(const char *path, char *buf, int n)
{
    FILE *f = fopen(path, "r");
    int ok;
    if (!f) return 0;
    ok = fgets(buf, n, f) != NULL;
    fclose(f);
    return ok;
}

/* Bytes of one of CPU 0's data caches for each CPU that shares it, from Linux's sysfs
 * (/sys/devices/system/cpu/cpu0/cache): the last level's (below_last = 0), or the largest
 * level's below the last (below_last /= 0: the largest the CPU keeps for itself; the last
 * level's where it is the only one); 0 when it cannot be read. */
long iem_cache_share(int below_last)
{
    char path[128], buf[256], *end;
    long level_of[16], share_of[16], top = 0, pick = 0, level, size, cpus, share = 0;
    int i, n = 0;
    for (i = 0; i < 16; i++) {
        snprintf(path, sizeof path, "/sys/devices/system/cpu/cpu0/cache/index%d/type", i);
        if (!read_line(path, buf, sizeof buf)) continue;
        if (strncmp(buf, "Instruction", 11) == 0) continue;
        snprintf(path, sizeof path, "/sys/devices/system/cpu/cpu0/cache/index%d/level", i);
        if (!read_line(path, buf, sizeof buf)) continue;
        level = strtol(buf, NULL, 10);
        snprintf(path, sizeof path, "/sys/devices/system/cpu/cpu0/cache/index%d/size", i);
        if (!read_line(path, buf, sizeof buf)) continue;
        size = strtol(buf, &end, 10);
        if (*end == 'K') size *= 1024L;
        else if (*end == 'M') size *= 1024L * 1024L;
        else if (*end == 'G') size *= 1024L * 1024L * 1024L;
        snprintf(path, sizeof path, "/sys/devices/system/cpu/cpu0/cache/index%d/shared_cpu_list",
                 i);
        cpus = read_line(path, buf, sizeof buf) ? cpu_count(buf) : 0;
        if (level <= 0 || size <= 0 || cpus <= 0) continue;
        level_of[n] = level;
        share_of[n] = size / cpus;
        if (level > top) top = level;
        n++;
    }
    if (below_last)
        for (i = 0; i < n; i++)
            if (level_of[i] < top && level_of[i] > pick) pick = level_of[i];
    if (pick == 0) pick = top;
    for (i = 0; i < n; i++)
        if (level_of[i] == pick && share_of[i] > share) share = share_of[i];
    return share;
}
