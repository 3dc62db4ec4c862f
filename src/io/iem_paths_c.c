/* The few POSIX calls that Fortran has no portable form of, for the file checks made before
 * a run writes anything (src/io/iem_paths.f90 holds their Fortran interfaces). */
#include <errno.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* What `path` is, following links: 0 nothing there, 1 a regular file, 2 a folder,
 * 3 something else (device, pipe, socket), -1 it cannot be looked at (permissions, a
 * dangling link, a name too long). */
int iem_path_kind(const char *path)
{
    struct stat st;
    if (stat(path, &st) != 0) {
        if (errno == ENOENT) {
            struct stat lst;
            /* a link whose target is missing is not "nothing there" */
            if (lstat(path, &lst) == 0) return -1;
            return 0;
        }
        return -1;
    }
    if (S_ISREG(st.st_mode)) return 1;
    if (S_ISDIR(st.st_mode)) return 2;
    return 3;
}

/* 1 when `path` (a folder) can be written into and entered by this process, else 0. */
int iem_folder_writable(const char *path)
{
    return access(path, W_OK | X_OK) == 0 ? 1 : 0;
}

/* 1 when `path` can be read by this process, else 0. */
int iem_file_readable(const char *path)
{
    return access(path, R_OK) == 0 ? 1 : 0;
}

/* The absolute path of an existing `path` with links, '.' and '..' resolved, into `out`
 * (NUL-terminated, at most `n` bytes); returns its length, or -1 when it cannot be resolved. */
int iem_resolve(const char *path, char *out, int n)
{
    char buf[PATH_MAX];
    if (realpath(path, buf) == NULL) return -1;
    size_t len = strlen(buf);
    if ((long)len + 1 > (long)n) return -1;
    memcpy(out, buf, len + 1);
    return (int)len;
}
