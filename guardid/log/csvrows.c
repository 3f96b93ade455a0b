/*
 * Rows of plain decimals (guardid's log body) parsed into the caller's float64 columns.
 *
 * C99, no allocation: the caller passes, for each of the ncols columns, the address of the
 * element to write for the first row and the row stride (in doubles). A field is
 * -?[0-9]+(\.[0-9]+)?, fields are separated by ',' and a row ends in '\n'. Its digits,
 * point dropped, are read as an integer v < 2^53 and divided by 10^d (d <= 22 digits after
 * the point): both exact in a double, so the quotient is the correctly rounded value of
 * the decimal, what float(text) gives, bit for bit (the sign applied after: -0.000 is
 * -0.0). Anything else (an empty field, a NaN, a space, a CR, another field count, more
 * digits) stops the parse at the start of its row: the caller reads the rest its own way.
 */
#include <stdint.h>

#define EXACT_LIMIT (((uint64_t)1) << 53) /* every integer below is exact in a double */
#define MAX_DECIMALS 22                    /* 10^22 is the largest power of ten exact */
#define MAX_DIGITS 19                      /* 19 digits never overflow a uint64_t */

static const double POW10[MAX_DECIMALS + 1] = {
    1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
    1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
};

/*
 * Parse whole rows of ncols fields from text[start, len), at most max_rows of them,
 * writing field c of row r to cols[c][r * strides[c]]. Returns the rows parsed; *used is
 * the offset in text after them (the start of the first row not parsed). Fields of a row
 * that stops midway may have been written (the caller's buffers have room for max_rows).
 */
long guardid_csv_rows(const char *text, long start, long len, long ncols,
                      double *const *cols, const long *strides, long max_rows, long *used)
{
    const unsigned char *p = (const unsigned char *)text + start;
    const unsigned char *limit = (const unsigned char *)text + len;
    const unsigned char *row = p;
    long r = 0;
    /* Up to the last '\n' only: every run of digits then ends before the limit. */
    while (limit > p && limit[-1] != '\n') {
        limit--;
    }
    while (r < max_rows && p < limit) {
        long c;
        for (c = 0; c < ncols; c++) {
            const unsigned char *first;
            uint64_t v = 0;
            long decimals = 0;
            int negative = *p == '-';
            double x;
            p += negative;
            first = p;
            while ((unsigned)(*p - '0') < 10u) {
                v = v * 10u + (uint64_t)(*p - '0'); /* wraps past 19 digits: refused below */
                p++;
            }
            if (p == first) {
                goto stop;
            }
            if (*p == '.') {
                const unsigned char *point = ++p;
                while ((unsigned)(*p - '0') < 10u) {
                    v = v * 10u + (uint64_t)(*p - '0');
                    p++;
                }
                decimals = (long)(p - point);
                if (decimals == 0 || decimals > MAX_DECIMALS) {
                    goto stop;
                }
            }
            if (p - first - (decimals > 0) > MAX_DIGITS || v >= EXACT_LIMIT) {
                goto stop;
            }
            if (*p != (c + 1 == ncols ? '\n' : ',')) {
                goto stop;
            }
            p++;
            x = (double)v / POW10[decimals];
            cols[c][r * strides[c]] = negative ? -x : x;
        }
        r++;
        row = p;
    }
stop:
    *used = (long)(row - (const unsigned char *)text);
    return r;
}
