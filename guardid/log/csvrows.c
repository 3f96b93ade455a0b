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
#define MAX_DIGITS 19 /* 19 significant digits never overflow a uint64_t */

static const double POW10[MAX_DECIMALS + 1] = {
    1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
    1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
};

/* The digits at *p (a run that ends before the limit) added to *v; returns how many.
 * *significant counts those from the first non-zero one on: past MAX_DIGITS of them *v
 * wraps around, which the caller refuses. */
static long digits(const unsigned char **p, uint64_t *v, long *significant)
{
    const unsigned char *s = *p;
    uint64_t x = *v;
    long n = *significant;
    while ((unsigned)(*s - '0') < 10u) {
        x = x * 10u + (uint64_t)(*s - '0');
        n += x != 0;
        s++;
    }
    *v = x;
    *significant = n;
    n = (long)(s - *p);
    *p = s;
    return n;
}

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
            uint64_t v = 0;
            long significant = 0;
            long decimals = 0;
            int negative = *p == '-';
            double x;
            p += negative;
            if (digits(&p, &v, &significant) == 0) {
                goto stop; /* an empty field, a '+', a space, a point first, ... */
            }
            if (*p == '.') {
                p++;
                decimals = digits(&p, &v, &significant);
                if (decimals == 0 || decimals > MAX_DECIMALS) {
                    goto stop;
                }
            }
            if (significant > MAX_DIGITS || v >= EXACT_LIMIT) {
                goto stop; /* not exact in a double */
            }
            if (*p != (c + 1 == ncols ? '\n' : ',')) {
                goto stop; /* another byte, another field count */
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
