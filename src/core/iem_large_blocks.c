/* Large heap blocks at staggered offsets in their pages (docs/architecture.md, "Large blocks'
 * offsets in their pages").
 *
 * glibc maps each large block (the per-node arrays) on its own pages and hands it out 16 bytes
 * into the first page, so every per-node array starts at the same offset in its page: node l's
 * values in the state, the update and the stage state then lie at the same offset in their
 * pages, and for some array lengths (the RK4 pass of 101,280 nodes, arrays 792 pages apart:
 * about 1.9 times as slow) the core's caches serve them far more slowly than otherwise; at 16
 * bytes into a line, one of every two 32-byte loads also spans two lines. Built with the
 * linker's --wrap of malloc, free and realloc (CMakeLists.txt, IEM_LARGE_BLOCKS), the
 * program's and the library's own allocations (gfortran's ALLOCATE calls malloc) go through
 * the functions here: a block of at least LARGE bytes starts on a cache line, its offset in
 * its page 64 + 1024 k for the k-th such block, k taken in turn 0..3, so that arrays made one
 * after the other lie a quarter of a page apart; smaller blocks are the C library's own.
 * The calls of the shared libraries (MPI, HDF5, the Fortran run time) are not wrapped: a block
 * they make is freed by free's pass-through, and none of them frees or resizes a block made
 * here (the program never hands one over).
 *
 * The staggered blocks are kept in a small open-addressing table (pointer -> the C library's
 * block and the size asked for); when it is three quarters full, a large block is the C
 * library's own, as a small one. A lock makes the table safe should threads allocate. */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h> /* defines __GLIBC__ where the C library is glibc */
#include <string.h>
#include <sys/mman.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif

void *__real_malloc(size_t n);
void __real_free(void *p);
void *__real_realloc(void *p, size_t n);
void *__wrap_malloc(size_t n);
void __wrap_free(void *p);
void *__wrap_realloc(void *p, size_t n);

enum { LARGE = 262144, PAGE = 4096, LINE = 64, SLOTS = 1024, MAX_LIVE = 3 * SLOTS / 4 };
/* the size of a huge page (x86-64's and most systems' transparent huge pages), and the size
 * from which a block asks for them */
#define HUGE_PAGE ((uintptr_t)2 << 20)
#define HUGE_FROM ((size_t)4 << 20)

/* A staggered block: the pointer handed out (0: slot empty), the C library's block, the size. */
typedef struct {
  uintptr_t out;
  void *real;
  size_t size;
} entry_t;

static entry_t table[SLOTS];
static int live = 0;
static unsigned turn = 0;
static volatile int busy = 0;

static void lock(void) {
  while (__atomic_exchange_n(&busy, 1, __ATOMIC_ACQUIRE)) {
  }
}

static void unlock(void) { __atomic_store_n(&busy, 0, __ATOMIC_RELEASE); }

/* The table's home slot of a pointer. */
static size_t home(uintptr_t p) { return (size_t)(((p >> 6) * 0x9E3779B97F4A7C15ull) >> 54) % SLOTS; }

/* The slot of p in the table, or -1. */
static long find(uintptr_t p) {
  for (size_t i = 0, s = home(p); i < SLOTS; i++, s = (s + 1) % SLOTS) {
    if (table[s].out == p) return (long)s;
    if (table[s].out == 0) return -1;
  }
  return -1;
}

/* Empty slot s, moving the entries after it that would no longer be found (linear probing's
 * deletion without markers). */
static void erase(size_t s) {
  size_t gap = s;
  table[gap].out = 0;
  for (size_t j = (gap + 1) % SLOTS; table[j].out != 0; j = (j + 1) % SLOTS) {
    size_t h = home(table[j].out);
    /* the entry at j may move into the gap when its home is not in (gap, j] cyclically */
    int stays = (gap <= j) ? (h > gap && h <= j) : (h > gap || h <= j);
    if (!stays) {
      table[gap] = table[j];
      table[j].out = 0;
      gap = j;
    }
  }
  live--;
}

/* malloc: a block of n bytes; from LARGE bytes on, on a cache line at the next offset in turn
 * in its page, and from HUGE_FROM on, in huge pages where the system has them. */
void *__wrap_malloc(size_t n) {
  /* (a size the extra bytes would wrap around is the C library's to refuse) */
  if (n < LARGE || n > SIZE_MAX - PAGE - LINE) return __real_malloc(n);
  lock();
  if (live >= MAX_LIVE) {
    unlock();
    return __real_malloc(n);
  }
  unlock();
  char *real = __real_malloc(n + PAGE + LINE);
  if (real == NULL) return NULL;
#ifdef MADV_HUGEPAGE
  if (n >= HUGE_FROM) {
    /* the whole huge pages within the block may be backed by huge pages (where transparent
     * huge pages are left to madvise; a hint, its failure harmless) */
    uintptr_t lo = ((uintptr_t)real + HUGE_PAGE - 1) & ~(HUGE_PAGE - 1);
    uintptr_t hi = ((uintptr_t)real + n) & ~(HUGE_PAGE - 1);
    if (hi > lo) (void)madvise((void *)lo, hi - lo, MADV_HUGEPAGE);
  }
#endif
  lock();
  uintptr_t want = (LINE + 1024u * (turn++ % 4u)) % PAGE;
  uintptr_t out = (uintptr_t)real + ((want - (uintptr_t)real % PAGE) % PAGE);
  size_t s = home(out);
  while (table[s].out != 0) s = (s + 1) % SLOTS;
  table[s].out = out;
  table[s].real = real;
  table[s].size = n;
  live++;
  unlock();
  return (void *)out;
}

/* free: a block from either malloc. */
void __wrap_free(void *p) {
  if (p == NULL) return;
  void *real = p;
  lock();
  if (live > 0) {
    long s = find((uintptr_t)p);
    if (s >= 0) {
      real = table[s].real;
      erase((size_t)s);
    }
  }
  unlock();
  __real_free(real);
}

/* realloc: a staggered block moves to a new block of n bytes (staggered when large), as does a
 * small block of the C library's grown into a large one (with glibc, which tells a block's
 * size); any other is the C library's. */
void *__wrap_realloc(void *p, size_t n) {
  if (p == NULL) return __wrap_malloc(n);
  lock();
  long s = live > 0 ? find((uintptr_t)p) : -1;
  size_t old = s >= 0 ? table[s].size : 0;
  unlock();
  if (s < 0) {
#ifdef __GLIBC__
    /* a small block grown into a large one moves to a staggered block */
    size_t usable = malloc_usable_size(p);
    if (n >= LARGE && usable < LARGE) {
      void *q = __wrap_malloc(n);
      if (q == NULL) return NULL;
      memcpy(q, p, usable < n ? usable : n);
      __real_free(p);
      return q;
    }
#endif
    return __real_realloc(p, n);
  }
  if (n == 0) {
    __wrap_free(p);
    return NULL;
  }
  void *q = __wrap_malloc(n);
  if (q == NULL) return NULL;
  memcpy(q, p, old < n ? old : n);
  __wrap_free(p);
  return q;
}
