/* gp_pyext.c: the protocol's C codec (guard_proto.c, guard_proto_msgs.h) as a CPython
 * extension for the host's hot paths (guardid.protocol.fastcodec): one call per frame
 * packed, one per chunk parsed, the Python objects made here. Not a second codec: the
 * layouts are gp_flat_pack / gp_flat_unpack's, COBS is gp_cobs_*; only the CRC (the same
 * function) runs from a table, as the host can spare the 1 KiB a microcontroller cannot.
 * C99, no allocation but the Python objects returned.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "../guard_proto.h"

static uint32_t crc_table[256];

static void crc_init(void)
{
    unsigned b, k;
    for (b = 0; b < 256u; ++b) {
        uint32_t c = b;
        for (k = 0; k < 8u; ++k)
            c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
        crc_table[b] = c;
    }
}

/* gp_crc32 (zlib.crc32), a byte at a time. */
static uint32_t crc32_table(const uint8_t *data, size_t len)
{
    uint32_t crc = 0xFFFFFFFFu;
    size_t i;
    for (i = 0; i < len; ++i)
        crc = (crc >> 8) ^ crc_table[(crc ^ data[i]) & 0xFFu];
    return crc ^ 0xFFFFFFFFu;
}

#define MAX_VALS 64

/* The configuration of a message's frames (see encode): 0 when cfg is not one. */
static Py_ssize_t read_cfg(const char *bytes, Py_ssize_t len, int64_t *cfg)
{
    Py_ssize_t n_vals;
    if (len < 24 || (size_t)len > sizeof(int64_t) * (3 + 2 * MAX_VALS))
        return 0;
    memcpy(cfg, bytes, (size_t)len);
    n_vals = (Py_ssize_t)cfg[2];
    return n_vals > 0 && n_vals <= MAX_VALS && len == 8 * (3 + 2 * n_vals) ? n_vals : 0;
}

/* v[k] = item k of the sequence items (ints), checked against the ranges of cfg; 0 when
   one is not an int or out of range. */
static int read_vals(const int64_t *cfg, Py_ssize_t k0, PyObject *items, int64_t *v)
{
    Py_ssize_t k, n = PySequence_Fast_GET_SIZE(items), n_vals = (Py_ssize_t)cfg[2];
    PyObject **obj = PySequence_Fast_ITEMS(items);
    if (k0 + n != n_vals)
        return 0;
    for (k = 0; k < n; ++k) {
        int overflow = 0;
        long long x;
        if (!PyLong_Check(obj[k]))
            return 0;
        x = PyLong_AsLongLongAndOverflow(obj[k], &overflow);
        if (overflow || x < cfg[3 + k0 + k] || x > cfg[3 + n_vals + k0 + k])
            return 0;
        v[k0 + k] = (int64_t)x;
    }
    return 1;
}

/* The wire frame (delimiter included) of values v numbered seq into out (GP_MAX_WIRE
   bytes); its length, 0 if gp_flat_pack refuses. */
static size_t frame_of(const int64_t *cfg, const int64_t *v, unsigned seq, uint8_t *out)
{
    uint8_t raw[GP_MAX_RAW], payload[GP_MAX_PAYLOAD];
    int len = gp_flat_pack((uint8_t)cfg[0], v, (unsigned)cfg[1], payload);
    size_t n;
    if (len < 0 || (size_t)len > GP_MAX_PAYLOAD)
        return 0;
    raw[0] = (uint8_t)GP_FRAME_VERSION;
    raw[1] = (uint8_t)cfg[0];
    gp_put_u16(raw + 2, seq & 0xFFFFu);
    memcpy(raw + GP_HEADER_LEN, payload, (size_t)len);
    gp_put_u32(raw + GP_HEADER_LEN + len, crc32_table(raw, GP_HEADER_LEN + (size_t)len));
    n = gp_cobs_encode(raw, GP_MIN_RAW + (size_t)len, out);
    out[n] = 0u;
    return n + 1u;
}

/* encode(cfg, seq, values) -> bytes | None: the wire frame (delimiter included) of one
   message from its flattened values (a tuple of ints), numbered seq. cfg: int64s packed
   native: message id, joint count, value count n, the n smallest and n largest values.
   None when a value is not an int or out of its field's range (the caller's Python path
   then says which). */
static PyObject *py_encode(PyObject *self, PyObject *args)
{
    const char *cfg_bytes;
    Py_ssize_t cfg_len;
    unsigned int seq;
    PyObject *vals;
    int64_t cfg[3 + 2 * MAX_VALS], v[MAX_VALS];
    uint8_t out[GP_MAX_WIRE];
    size_t n;
    (void)self;
    if (!PyArg_ParseTuple(args, "y#IO!", &cfg_bytes, &cfg_len, &seq, &PyTuple_Type, &vals))
        return NULL;
    if (!read_cfg(cfg_bytes, cfg_len, cfg) || !read_vals(cfg, 0, vals, v))
        Py_RETURN_NONE;
    n = frame_of(cfg, v, seq, out);
    if (n == 0)
        Py_RETURN_NONE;
    return PyBytes_FromStringAndSize((const char *)out, (Py_ssize_t)n);
}

/* encode_rows(cfg, seq, tick, flags, rows, start, count) -> bytes | None: the frames of
   count messages numbered seq, seq + 1, ... whose values are (tick + i) mod 2**32, flags,
   then the ints of rows[start + i] (a streamed SETPOINT or SETPOINT_FF per tick); None as
   encode, nothing encoded then. */
static PyObject *py_encode_rows(PyObject *self, PyObject *args)
{
    const char *cfg_bytes;
    Py_ssize_t cfg_len, start, count, i;
    unsigned int seq;
    unsigned long long tick, flags;
    PyObject *rows, *result;
    int64_t cfg[3 + 2 * MAX_VALS], v[MAX_VALS];
    char *out;
    size_t o = 0;
    (void)self;
    if (!PyArg_ParseTuple(args, "y#IKKOnn", &cfg_bytes, &cfg_len, &seq, &tick, &flags, &rows,
                          &start, &count))
        return NULL;
    if (!read_cfg(cfg_bytes, cfg_len, cfg) || cfg[2] < 3 || count < 0)
        Py_RETURN_NONE;
    result = PyBytes_FromStringAndSize(NULL, count * (Py_ssize_t)GP_MAX_WIRE);
    if (result == NULL)
        return NULL;
    out = PyBytes_AS_STRING(result);
    for (i = 0; i < count; ++i) {
        PyObject *row = PySequence_GetItem(rows, start + i), *items;
        int ok;
        size_t n = 0;
        if (row == NULL) {
            Py_DECREF(result);
            return NULL;
        }
        items = PySequence_Fast(row, "a row must be a sequence");
        Py_DECREF(row);
        if (items == NULL) {
            Py_DECREF(result);
            return NULL;
        }
        v[0] = (int64_t)((tick + (unsigned long long)i) & 0xFFFFFFFFull);
        v[1] = (int64_t)flags;
        ok = v[1] >= cfg[4] && v[1] <= cfg[4 + cfg[2]] && read_vals(cfg, 2, items, v);
        Py_DECREF(items);
        if (ok)
            n = frame_of(cfg, v, seq + (unsigned)i, (uint8_t *)out + o);
        if (n == 0) {
            Py_DECREF(result);
            Py_RETURN_NONE;
        }
        o += n;
    }
    if (_PyBytes_Resize(&result, (Py_ssize_t)o) != 0)
        return NULL;
    return result;
}

/* An empty instance of cls (a tuple type) of n items, filled by the caller: what
   tuple.__new__(cls, items) makes, without the items' tuple. */
static PyObject *new_tuple(PyObject *cls, Py_ssize_t n)
{
    PyTypeObject *type = (PyTypeObject *)cls;
    return type == &PyTuple_Type ? PyTuple_New(n) : type->tp_alloc(type, n);
}

/* Item k of the new tuple t = the int x; 0 when the int cannot be made. */
static int set_int(PyObject *t, Py_ssize_t k, long long x)
{
    PyObject *o = PyLong_FromLongLong(x);
    if (o == NULL)
        return 0;
    PyTuple_SET_ITEM(t, k, o);
    return 1;
}

/* The message of a decoded frame: cls(n_fixed ints, then the per-joint arrays as tuples). */
static PyObject *message(const int64_t *v, int nv, unsigned nj, Py_ssize_t n_fixed,
                         PyObject *cls)
{
    Py_ssize_t n_arrays = nj ? (nv - n_fixed) / (Py_ssize_t)nj : 0, k, j;
    PyObject *msg = new_tuple(cls, n_fixed + n_arrays);
    if (msg == NULL)
        return NULL;
    for (k = 0; k < n_fixed; ++k)
        if (!set_int(msg, k, v[k])) {
            Py_DECREF(msg);
            return NULL;
        }
    for (k = 0; k < n_arrays; ++k) {
        PyObject *arr = PyTuple_New((Py_ssize_t)nj);
        if (arr == NULL) {
            Py_DECREF(msg);
            return NULL;
        }
        PyTuple_SET_ITEM(msg, n_fixed + k, arr);
        for (j = 0; j < (Py_ssize_t)nj; ++j)
            if (!set_int(arr, j, v[n_fixed + k * (Py_ssize_t)nj + j])) {
                Py_DECREF(msg);
                return NULL;
            }
    }
    return msg;
}

/* frame_cls((msg_id, seq, msg)), msg stolen. */
static PyObject *frame(PyObject *frame_cls, int id, unsigned seq, PyObject *msg)
{
    PyObject *f = new_tuple(frame_cls, 3);
    if (f == NULL) {
        Py_DECREF(msg);
        return NULL;
    }
    PyTuple_SET_ITEM(f, 2, msg);
    if (!set_int(f, 0, id) || !set_int(f, 1, seq)) {
        Py_DECREF(f);
        return NULL;
    }
    return f;
}

/* scan(data, msg_id, raw_len, seq, n_fixed, cls, frame_cls) -> (list, used, next_seq):
   the leading segments of data (0x00-delimited; empty segments are idle fill) that are
   valid frames of msg_id decoding to raw_len bytes, numbered in sequence from seq (-1: any
   first number): the frames a FrameParser takes without counting anything but a frame.
   Stops at the first other segment (an error, a gap, another message, a segment without
   its delimiter yet), left to the caller. Each message is cls(fields) (n_fixed fixed
   fields, then the per-joint arrays as tuples), wrapped in frame_cls((msg_id, seq, msg))
   unless frame_cls is None; used: the bytes of data they took. */
static PyObject *py_scan(PyObject *self, PyObject *args)
{
    const uint8_t *data;
    Py_ssize_t len, raw_len, n_fixed, i = 0, start = 0, used = 0;
    int id, seq;
    PyObject *cls, *frame_cls, *list, *result;
    uint8_t raw[GP_MAX_ENCODED];
    int64_t v[MAX_VALS];
    (void)self;
    if (!PyArg_ParseTuple(args, "y#ininOO", &data, &len, &id, &raw_len, &seq, &n_fixed, &cls,
                          &frame_cls))
        return NULL;
    if (!PyType_Check(cls) || !PyType_IsSubtype((PyTypeObject *)cls, &PyTuple_Type) ||
        (frame_cls != Py_None && (!PyType_Check(frame_cls) ||
                                  !PyType_IsSubtype((PyTypeObject *)frame_cls, &PyTuple_Type)))) {
        PyErr_SetString(PyExc_TypeError, "scan: cls and frame_cls must be tuple types");
        return NULL;
    }
    if (n_fixed < 0 || n_fixed > MAX_VALS) { /* message() indexes v and the tuple by it */
        PyErr_SetString(PyExc_ValueError, "scan: n_fixed out of range");
        return NULL;
    }
    list = PyList_New(0);
    if (list == NULL)
        return NULL;
    while (i < len && raw_len >= (Py_ssize_t)GP_MIN_RAW && raw_len <= (Py_ssize_t)GP_MAX_RAW) {
        size_t n;
        unsigned nj;
        int nv;
        uint16_t got;
        PyObject *obj;
        if (data[i] == 0u) { /* idle fill */
            start = ++i;
            continue;
        }
        while (i < len && data[i] != 0u)
            ++i;
        if (i == len || i - start > (Py_ssize_t)GP_MAX_ENCODED)
            break;
        if (gp_cobs_decode(data + start, (size_t)(i - start), raw, &n) != 0 ||
            n != (size_t)raw_len)
            break;
        if (crc32_table(raw, n - GP_CRC_LEN) != gp_get_u32(raw + n - GP_CRC_LEN))
            break;
        got = (uint16_t)gp_get_u16(raw + 2);
        if (raw[0] != GP_FRAME_VERSION || raw[1] != (uint8_t)id || (seq >= 0 && got != seq))
            break;
        nv = gp_flat_unpack(raw[1], raw + GP_HEADER_LEN, n - GP_MIN_RAW, v, &nj);
        if (nv < n_fixed || nv > MAX_VALS)
            break;
        obj = message(v, nv, nj, n_fixed, cls);
        if (obj != NULL && frame_cls != Py_None)
            obj = frame(frame_cls, id, got, obj);
        if (obj == NULL || PyList_Append(list, obj) != 0) {
            Py_XDECREF(obj);
            Py_DECREF(list);
            return NULL;
        }
        Py_DECREF(obj);
        seq = (int)(uint16_t)(got + 1u);
        start = ++i;
        used = i;
    }
    result = Py_BuildValue("(Nni)", list, used, seq);
    return result;
}

static PyMethodDef methods[] = {
    {"encode", py_encode, METH_VARARGS, "One wire frame from flattened values, or None."},
    {"encode_rows", py_encode_rows, METH_VARARGS, "Streamed setpoint frames from rows."},
    {"scan", py_scan, METH_VARARGS, "The leading valid frames of one kind in a chunk."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "gp_pyext", "The protocol's C codec for the host's hot paths.", -1,
    methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit_gp_pyext(void)
{
    crc_init();
    return PyModule_Create(&module);
}
