/* What the crash guard (cw_guard.c) lends the logger (cw_log.c): a string
 * an FMU passed, read without trusting it. POSIX only, as both files. */
#ifndef CW_GUARD_H
#define CW_GUARD_H

#include <stddef.h>

/* The NUL-terminated string at src, at most cap - 1 bytes of it, into dst
 * (always terminated): its length, or -1 when src cannot be read at all. */
long cw_safe_string(char *dst, size_t cap, const char *src);

#endif
