/* The layout of every struct that Python mirrors with ctypes, exported
 * field by field (name, offset, size, alignment) so that the Python side
 * checks each of its fields, not only the struct's size: two swapped fields
 * of one type keep the size and would pass a sizeof check.
 *
 * A table is written beside its struct. A mirrored struct has no implicit
 * padding (where alignment needs it, an explicit pad_ field), so Python can
 * also check that its table covers it: the fields, in offset order, leave
 * no gap and end where sizeof says. A field added to the struct and left
 * out of the table (and of the mirror) is found that way. */
#ifndef CW_LAYOUT_H
#define CW_LAYOUT_H

#include <stddef.h>

typedef struct {
    const char *name;
    size_t offset, size, align;
} cw_field;

#define CW_FIELD(type, field) \
    { #field, offsetof(type, field), sizeof(((type *)0)->field), __alignof__(((type *)0)->field) }

#define CW_COUNT(table) (sizeof(table) / sizeof((table)[0]))

/* In a lookup function of (name, n_fields, struct_size): the table
 * tag_layout of struct cw_tag when name is "tag". */
#define CW_LAYOUT_CASE(tag)                            \
    if (!strcmp(name, #tag)) {                         \
        *n_fields = CW_COUNT(tag##_layout);            \
        *struct_size = sizeof(cw_##tag);               \
        return tag##_layout;                           \
    }

#endif
