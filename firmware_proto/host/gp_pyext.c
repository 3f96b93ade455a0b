/* gp_pyext.c: the protocol's C codec (guard_proto.c, guard_proto_msgs.h) as a CPython
 * extension for the host's hot paths (guardid.protocol.fastcodec): one call per frame
 * packed, one per chunk parsed, the Python objects made here. Not a second codec: the
 * layouts are gp_flat_pack / gp_flat_unpack's, COBS is gp_cobs_*; only the CRC (the same
 * function) runs from a table, as the host can spare the 1 KiB a microcontroller cannot.
 * Also the firmware emulator's (guardid/firmware/emulator.py) per-tick arithmetic: pid_pwm,
 * telemetry, the same integers and bytes as its Python path (tests/test_firmware_fast.py).
 * C99, no allocation but the Python objects returned.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

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


/* The firmware emulator's position-mode tick (guardid.firmware.emulator), its integers as
   guardid.firmware.pid.FixedPid.step and emulator.pwm_mv compute them. */
static PyObject *s_limit_mv, *s_kp, *s_ki, *s_kd, *s_integral, *s_prev_error, *s_saturated;

#define PID_BOUND (1LL << 30) /* gains, positions, errors: the products stay in int64 */
#define MV_BOUND (1LL << 20)  /* limit and feedforward [mV] */

/* *out = the int attribute name of obj within +-bound; 0 when not (or on an error). */
static int int_attr(PyObject *obj, PyObject *name, long long bound, int64_t *out)
{
    int overflow = 0, is_int;
    long long x;
    PyObject *value = PyObject_GetAttr(obj, name);
    if (value == NULL) {
        PyErr_Clear();
        return 0;
    }
    is_int = PyLong_Check(value);
    x = is_int ? PyLong_AsLongLongAndOverflow(value, &overflow) : 0;
    Py_DECREF(value);
    if (!is_int || overflow || (x == -1 && PyErr_Occurred()) || x > bound || x < -bound) {
        PyErr_Clear();
        return 0;
    }
    *out = (int64_t)x;
    return 1;
}

/* v[j] = int item j of the list items within +-bound; 0 when not. */
static int int_items(PyObject *items, Py_ssize_t n, long long bound, int64_t *v)
{
    Py_ssize_t j;
    if (!PyList_Check(items) || PyList_GET_SIZE(items) != n)
        return 0;
    for (j = 0; j < n; ++j) {
        int overflow = 0;
        PyObject *o = PyList_GET_ITEM(items, j);
        long long x = PyLong_Check(o) ? PyLong_AsLongLongAndOverflow(o, &overflow) : 0;
        if (!PyLong_Check(o) || overflow || (x == -1 && PyErr_Occurred()) || x > bound ||
            x < -bound) {
            PyErr_Clear();
            return 0;
        }
        v[j] = (int64_t)x;
    }
    return 1;
}

#define MAX_TICK_JOINTS 8
#define DRIVE_VALS 7 /* per joint: has limits, low, high [counts], levels, supply [mV], bits */

/* pid_pwm(pids, setpoint, counts, feedforward, drives) -> (applied [mV] list, status, the
   same in V: mv * 1e-3) | None:
   one position-mode tick: each joint's PID step (FixedPid.step: its state updated), then
   the stop at a position limit and the PWM quantisation. drives: per joint the int64s has
   limits, low, high, PWM levels, supply [mV], saturated bit, limit bit. None (nothing
   changed) when a value is not an int of the range this int64 arithmetic is exact for. */
static PyObject *py_pid_pwm(PyObject *self, PyObject *args)
{
    PyObject *pids, *setpoint, *counts, *feedforward, *applied, *volts, *result;
    const char *drives_bytes;
    Py_ssize_t drives_len, n, j;
    int64_t drive[MAX_TICK_JOINTS * DRIVE_VALS], sp[MAX_TICK_JOINTS], pos[MAX_TICK_JOINTS];
    int64_t ff[MAX_TICK_JOINTS], integral[MAX_TICK_JOINTS], error[MAX_TICK_JOINTS];
    int64_t out[MAX_TICK_JOINTS];
    int saturated[MAX_TICK_JOINTS];
    int64_t status = 0;
    (void)self;
    if (!PyArg_ParseTuple(args, "O!OOOy#", &PyList_Type, &pids, &setpoint, &counts,
                          &feedforward, &drives_bytes, &drives_len))
        return NULL;
    n = PyList_GET_SIZE(pids);
    if (n < 1 || n > MAX_TICK_JOINTS || drives_len != (Py_ssize_t)(8 * DRIVE_VALS) * n)
        Py_RETURN_NONE;
    memcpy(drive, drives_bytes, (size_t)drives_len);
    if (!int_items(setpoint, n, PID_BOUND / 2, sp) || !int_items(counts, n, PID_BOUND / 2, pos) ||
        !int_items(feedforward, n, MV_BOUND, ff))
        Py_RETURN_NONE;
    for (j = 0; j < n; ++j) {
        PyObject *pid = PyList_GET_ITEM(pids, j);
        const int64_t *d = drive + DRIVE_VALS * j;
        int64_t limit, kp, ki, kd, prev, lim_q, raw, mv, duty;
        if (!int_attr(pid, s_limit_mv, MV_BOUND, &limit) || !int_attr(pid, s_kp, PID_BOUND, &kp) ||
            !int_attr(pid, s_ki, PID_BOUND, &ki) || !int_attr(pid, s_kd, PID_BOUND, &kd) ||
            !int_attr(pid, s_integral, 1LL << 40, &integral[j]) ||
            !int_attr(pid, s_prev_error, PID_BOUND, &prev) || d[3] < 1 || d[4] < 1)
            Py_RETURN_NONE;
        error[j] = sp[j] - pos[j];
        lim_q = limit * 65536;
        integral[j] += ki * error[j];
        if (integral[j] > lim_q)
            integral[j] = lim_q;
        else if (integral[j] < -lim_q)
            integral[j] = -lim_q;
        raw = kp * error[j] + integral[j] + kd * (error[j] - prev) + ff[j] * 65536;
        mv = raw >= 0 ? raw >> 16 : -((-raw) >> 16);
        saturated[j] = mv > limit || mv < -limit;
        if (saturated[j]) {
            status |= d[5];
            mv = mv > 0 ? limit : -limit;
            if ((error[j] > 0) == (mv > 0))
                integral[j] = INT64_MIN; /* the integral stays as it was */
        }
        if (d[0] && ((mv > 0 && pos[j] >= d[2]) || (mv < 0 && pos[j] <= d[1]))) {
            mv = 0;
            status |= d[6];
        }
        duty = ((mv < 0 ? -mv : mv) * d[3] + d[4] / 2) / d[4];
        duty = (duty * d[4] + d[3] / 2) / d[3];
        out[j] = mv >= 0 ? duty : -duty;
    }
    applied = PyList_New(n);
    volts = PyList_New(n);
    if (applied == NULL || volts == NULL) {
        Py_XDECREF(applied);
        Py_XDECREF(volts);
        return NULL;
    }
    for (j = 0; j < n; ++j) {
        PyObject *o = PyLong_FromLongLong(out[j]);
        PyObject *v = PyFloat_FromDouble((double)out[j] * 1e-3); /* Python's mv * 1e-3 */
        if (o == NULL || v == NULL) {
            Py_XDECREF(o);
            Py_XDECREF(v);
            Py_DECREF(applied);
            Py_DECREF(volts);
            return NULL;
        }
        PyList_SET_ITEM(applied, j, o);
        PyList_SET_ITEM(volts, j, v);
    }
    for (j = 0; j < n; ++j) { /* the state, once every joint's step is known */
        PyObject *pid = PyList_GET_ITEM(pids, j);
        PyObject *e = PyLong_FromLongLong(error[j]);
        PyObject *i = integral[j] == INT64_MIN ? NULL : PyLong_FromLongLong(integral[j]);
        int bad = e == NULL || (integral[j] != INT64_MIN && i == NULL) ||
                  PyObject_SetAttr(pid, s_saturated, saturated[j] ? Py_True : Py_False) ||
                  PyObject_SetAttr(pid, s_prev_error, e) ||
                  (i != NULL && PyObject_SetAttr(pid, s_integral, i));
        Py_XDECREF(e);
        Py_XDECREF(i);
        if (bad) {
            Py_DECREF(applied);
            Py_DECREF(volts);
            return NULL;
        }
    }
    result = Py_BuildValue("(NLN)", applied, (long long)status, volts);
    return result;
}


/* v[k0 + j] = the int item j of the list items in its field's range of cfg; 0 when not. */
static int read_list(const int64_t *cfg, Py_ssize_t k0, PyObject *items, Py_ssize_t n, int64_t *v)
{
    Py_ssize_t j, n_vals = (Py_ssize_t)cfg[2];
    if (!PyList_Check(items) || PyList_GET_SIZE(items) != n || k0 + n > n_vals)
        return 0;
    for (j = 0; j < n; ++j) {
        int overflow = 0;
        PyObject *o = PyList_GET_ITEM(items, j);
        long long x = PyLong_Check(o) ? PyLong_AsLongLongAndOverflow(o, &overflow) : 0;
        if (!PyLong_Check(o) || overflow || (x == -1 && PyErr_Occurred()) ||
            x < cfg[3 + k0 + j] || x > cfg[3 + n_vals + k0 + j]) {
            PyErr_Clear();
            return 0;
        }
        v[k0 + j] = (int64_t)x;
    }
    return 1;
}

/* v[k0 + j] = the float item j of the list items [units] in milli-units, rounded half up
   (Python's floor(x * 1000.0 + 0.5)) and clamped to int16; 0 when one is not a finite
   float. */
static int read_milli(PyObject *items, Py_ssize_t n, Py_ssize_t k0, int64_t *v)
{
    Py_ssize_t j;
    if (!PyList_Check(items) || PyList_GET_SIZE(items) != n)
        return 0;
    for (j = 0; j < n; ++j) {
        PyObject *o = PyList_GET_ITEM(items, j);
        double x, m;
        if (!PyFloat_Check(o))
            return 0;
        x = PyFloat_AS_DOUBLE(o);
        if (!(x - x == 0.0)) /* inf or nan: the Python path says so */
            return 0;
        m = floor(x * 1000.0 + 0.5);
        v[k0 + j] = m < -32768.0 ? -32768 : m > 32767.0 ? 32767 : (int64_t)m;
    }
    return 1;
}

/* telemetry(cfg, seq, tick, status, mode, counts, volts, amps, setpoint) -> bytes | None:
   the firmware emulator's TELEMETRY frame numbered seq (cfg as encode's) from the encoder
   counts, the voltages [V] and currents [A] (floats, to mV and mA as the emulator rounds
   and clamps them) and the setpoint (lists of n); None when a value is not of its kind or
   out of its field's range (the emulator's Python path then). */
static PyObject *py_telemetry(PyObject *self, PyObject *args)
{
    const char *cfg_bytes;
    Py_ssize_t cfg_len, n;
    unsigned int seq;
    long long tick, status, mode;
    PyObject *counts, *volts, *amps, *setpoint;
    int64_t cfg[3 + 2 * MAX_VALS], v[MAX_VALS];
    uint8_t out[GP_MAX_WIRE];
    size_t len;
    (void)self;
    if (!PyArg_ParseTuple(args, "y#ILLLOOOO", &cfg_bytes, &cfg_len, &seq, &tick, &status,
                          &mode, &counts, &volts, &amps, &setpoint))
        return NULL;
    if (!read_cfg(cfg_bytes, cfg_len, cfg) || !PyList_Check(counts))
        Py_RETURN_NONE;
    n = PyList_GET_SIZE(counts);
    v[0] = tick;
    v[1] = status;
    v[2] = mode;
    if (3 + 4 * n != (Py_ssize_t)cfg[2] || v[0] < cfg[3] || v[0] > cfg[3 + cfg[2]] ||
        v[1] < cfg[4] || v[1] > cfg[4 + cfg[2]] || v[2] < cfg[5] || v[2] > cfg[5 + cfg[2]] ||
        !read_list(cfg, 3, counts, n, v) || !read_milli(volts, n, 3 + n, v) ||
        !read_milli(amps, n, 3 + 2 * n, v) || !read_list(cfg, 3 + 3 * n, setpoint, n, v))
        Py_RETURN_NONE;
    len = frame_of(cfg, v, seq, out);
    if (len == 0)
        Py_RETURN_NONE;
    return PyBytes_FromStringAndSize((const char *)out, (Py_ssize_t)len);
}

static PyMethodDef methods[] = {
    {"encode", py_encode, METH_VARARGS, "One wire frame from flattened values, or None."},
    {"encode_rows", py_encode_rows, METH_VARARGS, "Streamed setpoint frames from rows."},
    {"scan", py_scan, METH_VARARGS, "The leading valid frames of one kind in a chunk."},
    {"pid_pwm", py_pid_pwm, METH_VARARGS, "The firmware emulator's position-mode tick."},
    {"telemetry", py_telemetry, METH_VARARGS, "The firmware emulator's TELEMETRY frame."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "gp_pyext", "The protocol's C codec for the host's hot paths.", -1,
    methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit_gp_pyext(void)
{
    crc_init();
    s_limit_mv = PyUnicode_InternFromString("limit_mv");
    s_kp = PyUnicode_InternFromString("kp");
    s_ki = PyUnicode_InternFromString("ki");
    s_kd = PyUnicode_InternFromString("kd");
    s_integral = PyUnicode_InternFromString("integral");
    s_prev_error = PyUnicode_InternFromString("prev_error");
    s_saturated = PyUnicode_InternFromString("saturated");
    if (!s_limit_mv || !s_kp || !s_ki || !s_kd || !s_integral || !s_prev_error || !s_saturated)
        return NULL;
    return PyModule_Create(&module);
}
