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

/* The attribute name of obj, a new reference; NULL with an error set when it has none. obj
   may be an instance's __dict__ (the attributes the emulator and its PIDs set in their
   __init__, never class attributes: guardid.firmware.emulator checks): a dict lookup. */
static PyObject *get_attr(PyObject *obj, PyObject *name)
{
    PyObject *value;
    if (!PyDict_CheckExact(obj))
        return PyObject_GetAttr(obj, name);
    value = PyDict_GetItemWithError(obj, name);
    if (value == NULL && !PyErr_Occurred())
        PyErr_SetObject(PyExc_AttributeError, name);
    Py_XINCREF(value);
    return value;
}

/* obj.name = value (obj an object or its __dict__, as get_attr); -1 on an error. */
static int set_attr(PyObject *obj, PyObject *name, PyObject *value)
{
    return PyDict_CheckExact(obj) ? PyDict_SetItem(obj, name, value)
                                  : PyObject_SetAttr(obj, name, value);
}

/* *out = the int attribute name of obj (get_attr) within +-bound; 0 when not (or on an
   error). */
static int int_attr(PyObject *obj, PyObject *name, long long bound, int64_t *out)
{
    int overflow = 0, is_int;
    long long x;
    PyObject *value = get_attr(obj, name);
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

/* The __dict__ of the PID pids[j] (a new reference; NULL, no error left, without one). */
static PyObject *pid_dict(PyObject *pids, Py_ssize_t j)
{
    PyObject *d = PyObject_GenericGetDict(PyList_GET_ITEM(pids, j), NULL);
    if (d != NULL && !PyDict_CheckExact(d))
        Py_CLEAR(d);
    PyErr_Clear();
    return d;
}

/* One position-mode tick of n joints (FixedPid.step's arithmetic, then the stop at a position
   limit and the PWM quantisation): from the setpoints sp, positions pos [counts] and
   feedforward ff [mV], the PIDs' gains and state (their int attributes) and the drives
   (per joint: has limits, low, high, PWM levels, supply [mV], saturated bit, limit bit),
   the applied voltages out [mV], the status bits and each PID's new state (error, integral:
   INT64_MIN where it stays, saturated). 0 (nothing read is changed) when a PID's value is
   not an int of the range this int64 arithmetic is exact for. */
static int pid_tick(PyObject *pids, Py_ssize_t n, const int64_t *sp, const int64_t *pos,
                    const int64_t *ff, const int64_t *drive, int64_t *out, int64_t *error,
                    int64_t *integral, int *saturated, int64_t *status)
{
    Py_ssize_t j;
    for (j = 0; j < n; ++j) {
        PyObject *pid = pid_dict(pids, j);
        const int64_t *d = drive + DRIVE_VALS * j;
        int64_t limit, kp, ki, kd, prev, lim_q, raw, mv, duty;
        int ok = pid != NULL && int_attr(pid, s_limit_mv, MV_BOUND, &limit) &&
                 int_attr(pid, s_kp, PID_BOUND, &kp) && int_attr(pid, s_ki, PID_BOUND, &ki) &&
                 int_attr(pid, s_kd, PID_BOUND, &kd) &&
                 int_attr(pid, s_integral, 1LL << 40, &integral[j]) &&
                 int_attr(pid, s_prev_error, PID_BOUND, &prev) && d[3] >= 1 && d[4] >= 1;
        Py_XDECREF(pid);
        if (!ok)
            return 0;
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
            *status |= d[5];
            mv = mv > 0 ? limit : -limit;
            if ((error[j] > 0) == (mv > 0))
                integral[j] = INT64_MIN; /* the integral stays as it was */
        }
        if (d[0] && ((mv > 0 && pos[j] >= d[2]) || (mv < 0 && pos[j] <= d[1]))) {
            mv = 0;
            *status |= d[6];
        }
        duty = ((mv < 0 ? -mv : mv) * d[3] + d[4] / 2) / d[4];
        duty = (duty * d[4] + d[3] / 2) / d[3];
        out[j] = mv >= 0 ? duty : -duty;
    }
    return 1;
}

/* *applied, *volts = new lists of out [mV] and of the same in V (Python's mv * 1e-3); 0 on
   a Python error (set). */
static int applied_lists(const int64_t *out, Py_ssize_t n, PyObject **applied, PyObject **volts)
{
    Py_ssize_t j;
    *applied = PyList_New(n);
    *volts = PyList_New(n);
    if (*applied == NULL || *volts == NULL)
        goto fail;
    for (j = 0; j < n; ++j) {
        PyObject *o = PyLong_FromLongLong(out[j]);
        PyObject *v = PyFloat_FromDouble((double)out[j] * 1e-3);
        if (o == NULL || v == NULL) {
            Py_XDECREF(o);
            Py_XDECREF(v);
            goto fail;
        }
        PyList_SET_ITEM(*applied, j, o);
        PyList_SET_ITEM(*volts, j, v);
    }
    return 1;
fail:
    Py_CLEAR(*applied);
    Py_CLEAR(*volts);
    return 0;
}

/* The PIDs' new state from pid_tick; 0 on a Python error (set). */
static int set_pid_state(PyObject *pids, Py_ssize_t n, const int64_t *error,
                         const int64_t *integral, const int *saturated)
{
    Py_ssize_t j;
    for (j = 0; j < n; ++j) {
        PyObject *pid = pid_dict(pids, j);
        PyObject *e = PyLong_FromLongLong(error[j]);
        PyObject *i = integral[j] == INT64_MIN ? NULL : PyLong_FromLongLong(integral[j]);
        int bad = pid == NULL || e == NULL || (integral[j] != INT64_MIN && i == NULL) ||
                  set_attr(pid, s_saturated, saturated[j] ? Py_True : Py_False) ||
                  set_attr(pid, s_prev_error, e) || (i != NULL && set_attr(pid, s_integral, i));
        if (pid == NULL) /* pid_tick read it: it had a __dict__ */
            PyErr_SetString(PyExc_RuntimeError, "a PID lost its __dict__");
        Py_XDECREF(pid);
        Py_XDECREF(e);
        Py_XDECREF(i);
        if (bad)
            return 0;
    }
    return 1;
}

/* pid_pwm(pids, setpoint, counts, feedforward, drives) -> (applied [mV] list, status, the
   same in V: mv * 1e-3) | None:
   one position-mode tick: each joint's PID step (FixedPid.step: its state updated), then
   the stop at a position limit and the PWM quantisation. drives: per joint the int64s has
   limits, low, high, PWM levels, supply [mV], saturated bit, limit bit. None (nothing
   changed) when a value is not an int of the range this int64 arithmetic is exact for. */
static PyObject *py_pid_pwm(PyObject *self, PyObject *args)
{
    PyObject *pids, *setpoint, *counts, *feedforward, *applied, *volts;
    const char *drives_bytes;
    Py_ssize_t drives_len, n;
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
        !int_items(feedforward, n, MV_BOUND, ff) ||
        !pid_tick(pids, n, sp, pos, ff, drive, out, error, integral, saturated, &status))
        Py_RETURN_NONE;
    if (!applied_lists(out, n, &applied, &volts))
        return NULL;
    if (!set_pid_state(pids, n, error, integral, saturated)) {
        Py_DECREF(applied);
        Py_DECREF(volts);
        return NULL;
    }
    return Py_BuildValue("(NLN)", applied, (long long)status, volts);
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

/* The emulator's attributes the whole tick and the setpoint handler read and write. */
static PyObject *s_mode, *s_applied_mv, *s_applied_of, *s_applied_v, *s_tick, *s_last_host_tick;
static PyObject *s_tick_us, *s_watchdog_ms, *s_read_plant, *s_buffer, *s_setpoint;
static PyObject *s_setpoint_hold, *s_feedforward_mv, *s_no_feedforward, *s_pids, *s_drives;
static PyObject *s_watchdog_tripped, *s_estop, *s_streaming, *s_decimation, *s_encoder, *s_seq;
static PyObject *s_telemetry_cfg, *s_out, *s_counts, *s_status, *s_popleft, *s_append;
static PyObject *s_last_frame, *s_last_reply;

#define TICK_MASK 0xFFFFFFFFLL
/* tick_diff(a, b) <= 0 for u32 ticks a, b (serial arithmetic, the emulator's inlined test) */
#define NOT_AFTER(a, b) ((((a) - (b) + 0x80000000LL) & TICK_MASK) <= 0x80000000LL)

/* The truth value of the attribute name of obj in *out; 0 on a Python error (set). */
static int true_attr(PyObject *obj, PyObject *name, int *out)
{
    PyObject *value = get_attr(obj, name);
    if (value == NULL)
        return 0;
    *out = PyObject_IsTrue(value);
    Py_DECREF(value);
    return *out >= 0;
}

/* The attribute name of obj, a new reference, when it is a (subclass of) type; NULL (no
   error left) when it is not or is missing. */
static PyObject *typed_attr(PyObject *obj, PyObject *name, PyTypeObject *type)
{
    PyObject *value = get_attr(obj, name);
    if (value == NULL)
        PyErr_Clear();
    else if (!PyObject_TypeCheck(value, type))
        Py_CLEAR(value);
    return value;
}

/* The whole position-mode tick of the emulator emu, up to the plant's read when it falls
   to the Python path; see py_fw_tick. The locals it reads, then writes. */
struct fw_tick {
    Py_ssize_t n, due;
    int64_t tick, status, seq;
    int64_t sp[MAX_TICK_JOINTS], pos[MAX_TICK_JOINTS], ff[MAX_TICK_JOINTS];
    int64_t out[MAX_TICK_JOINTS], error[MAX_TICK_JOINTS], integral[MAX_TICK_JOINTS];
    int saturated[MAX_TICK_JOINTS];
    uint8_t frame[GP_MAX_WIRE];
    size_t frame_len;
};

/* Everything the tick writes, from the plant's (counts, volts, amps) in sensed; 0 when the
   Python path must take it from there (nothing changed; a Python error set when one
   happened). k: position mode, underrun, watchdog and estop status bits. */
static int fw_plan(PyObject *emu, const int64_t *k, PyObject *sensed, PyObject *pids,
                   PyObject *buffer, PyObject *out_buf, PyObject *encoder, struct fw_tick *t,
                   PyObject **entry)
{
    PyObject *counts, *volts, *amps, *sp_obj = NULL, *ff_obj = NULL, *drives, *cfg_obj;
    Py_ssize_t nb, i;
    int64_t drive[MAX_TICK_JOINTS * DRIVE_VALS], cfg[3 + 2 * MAX_VALS], v[MAX_VALS], dec;
    int flag, ok = 0, streaming;
    if (!PyTuple_CheckExact(sensed) || PyTuple_GET_SIZE(sensed) != 3)
        return 0;
    counts = PyTuple_GET_ITEM(sensed, 0);
    volts = PyTuple_GET_ITEM(sensed, 1);
    amps = PyTuple_GET_ITEM(sensed, 2);
    t->n = PyList_GET_SIZE(pids);
    if (t->n < 1 || t->n > MAX_TICK_JOINTS || !int_items(counts, t->n, PID_BOUND / 2, t->pos))
        return 0;
    /* the buffer's due entries (popped in the commit), the last one's setpoint */
    nb = PyObject_Length(buffer);
    if (nb < 0)
        return 0;
    for (i = 0, t->due = 0; i < nb; ++i) {
        PyObject *e = PySequence_GetItem(buffer, i);
        int64_t at;
        if (e == NULL)
            return 0;
        if (!PyTuple_CheckExact(e) || PyTuple_GET_SIZE(e) < 3 || PyTuple_GET_SIZE(e) > 4 ||
            !PyLong_Check(PyTuple_GET_ITEM(e, 0))) {
            Py_DECREF(e);
            return 0;
        }
        at = PyLong_AsLongLong(PyTuple_GET_ITEM(e, 0));
        if (at < 0 || at > TICK_MASK) {
            PyErr_Clear();
            Py_DECREF(e);
            return 0;
        }
        if (!NOT_AFTER(at, t->tick)) {
            Py_DECREF(e);
            break;
        }
        Py_XSETREF(*entry, e);
        t->due += 1;
    }
    t->status = 0;
    if (t->due) {
        sp_obj = PyTuple_GET_ITEM(*entry, 1);
        Py_INCREF(sp_obj);
        if (PyTuple_GET_SIZE(*entry) > 3) {
            ff_obj = PyTuple_GET_ITEM(*entry, 3);
            Py_INCREF(ff_obj);
        } else {
            ff_obj = get_attr(emu, s_no_feedforward);
        }
    } else {
        if (!true_attr(emu, s_setpoint_hold, &flag))
            return 0;
        t->status |= flag ? 0 : k[1];
        sp_obj = get_attr(emu, s_setpoint);
        ff_obj = get_attr(emu, s_feedforward_mv);
    }
    drives = typed_attr(emu, s_drives, &PyBytes_Type);
    if (sp_obj != NULL && ff_obj != NULL && drives != NULL &&
        PyBytes_GET_SIZE(drives) == (Py_ssize_t)(8 * DRIVE_VALS) * t->n &&
        int_items(sp_obj, t->n, PID_BOUND / 2, t->sp) && int_items(ff_obj, t->n, MV_BOUND, t->ff)) {
        memcpy(drive, PyBytes_AS_STRING(drives), (size_t)PyBytes_GET_SIZE(drives));
        ok = pid_tick(pids, t->n, t->sp, t->pos, t->ff, drive, t->out, t->error, t->integral,
                      t->saturated, &t->status);
    }
    Py_XDECREF(drives);
    Py_XDECREF(ff_obj);
    if (!ok || !true_attr(emu, s_watchdog_tripped, &flag)) {
        Py_XDECREF(sp_obj);
        return 0;
    }
    t->status |= flag ? k[2] : 0;
    if (!true_attr(emu, s_estop, &flag) || !true_attr(emu, s_streaming, &streaming)) {
        Py_DECREF(sp_obj);
        return 0;
    }
    t->status |= flag ? k[3] : 0;
    t->frame_len = 0;
    ok = 1;
    if (streaming) { /* TELEMETRY(tick, status, mode, counts, mV, mA, setpoint) */
        ok = int_attr(emu, s_decimation, 1LL << 62, &dec) && dec >= 1;
        if (ok && t->tick % dec == 0) {
            cfg_obj = typed_attr(emu, s_telemetry_cfg, &PyBytes_Type);
            ok = cfg_obj != NULL && out_buf != NULL && encoder != NULL &&
                 read_cfg(PyBytes_AS_STRING(cfg_obj), PyBytes_GET_SIZE(cfg_obj), cfg) &&
                 int_attr(encoder, s_seq, 0xFFFF, &t->seq) && t->seq >= 0;
            Py_XDECREF(cfg_obj);
            v[0] = t->tick;
            v[1] = t->status;
            v[2] = k[0];
            ok = ok && 3 + 4 * t->n == (Py_ssize_t)cfg[2] && v[0] >= cfg[3] &&
                 v[0] <= cfg[3 + cfg[2]] && v[1] >= cfg[4] && v[1] <= cfg[4 + cfg[2]] &&
                 v[2] >= cfg[5] && v[2] <= cfg[5 + cfg[2]] && read_list(cfg, 3, counts, t->n, v) &&
                 read_milli(volts, t->n, 3 + t->n, v) && read_milli(amps, t->n, 3 + 2 * t->n, v) &&
                 read_list(cfg, 3 + 3 * t->n, sp_obj, t->n, v);
            t->frame_len = ok ? frame_of(cfg, v, (unsigned)t->seq, t->frame) : 0;
            ok = t->frame_len > 0;
        }
    }
    Py_DECREF(sp_obj);
    return ok;
}

/* The writes of a planned tick; 0 on a Python error (set). */
static int fw_commit(PyObject *emu, PyObject *sensed, PyObject *pids, PyObject *buffer,
                     PyObject *out_buf, PyObject *encoder, const struct fw_tick *t,
                     PyObject *entry)
{
    PyObject *applied, *volts, *x;
    Py_ssize_t i, size;
    int bad;
    for (i = 0; i < t->due; ++i) {
        x = PyObject_CallMethodObjArgs(buffer, s_popleft, NULL);
        if (x == NULL)
            return 0;
        Py_DECREF(x);
    }
    x = PyLong_FromLongLong(t->tick);
    bad = x == NULL || set_attr(emu, s_tick, x) ||
          set_attr(emu, s_counts, PyTuple_GET_ITEM(sensed, 0));
    Py_XDECREF(x);
    if (bad)
        return 0;
    if (t->due) {
        PyObject *ff = PyTuple_GET_SIZE(entry) > 3 ? PyTuple_GET_ITEM(entry, 3) : NULL;
        if (set_attr(emu, s_setpoint, PyTuple_GET_ITEM(entry, 1)) ||
            set_attr(emu, s_setpoint_hold, PyTuple_GET_ITEM(entry, 2)))
            return 0;
        ff = ff ? ff : get_attr(emu, s_no_feedforward);
        bad = ff == NULL || set_attr(emu, s_feedforward_mv, ff);
        if (PyTuple_GET_SIZE(entry) <= 3)
            Py_XDECREF(ff);
        if (bad)
            return 0;
    }
    if (!set_pid_state(pids, t->n, t->error, t->integral, t->saturated) ||
        !applied_lists(t->out, t->n, &applied, &volts))
        return 0;
    bad = set_attr(emu, s_applied_mv, applied) ||
          set_attr(emu, s_applied_of, applied) || set_attr(emu, s_applied_v, volts);
    Py_DECREF(applied);
    Py_DECREF(volts);
    x = bad ? NULL : PyLong_FromLongLong(t->status);
    bad = x == NULL || set_attr(emu, s_status, x);
    Py_XDECREF(x);
    if (bad || t->frame_len == 0)
        return !bad;
    x = PyLong_FromLongLong((t->seq + 1) & 0xFFFF);
    bad = x == NULL || set_attr(encoder, s_seq, x);
    Py_XDECREF(x);
    size = PyByteArray_GET_SIZE(out_buf);
    if (bad || PyByteArray_Resize(out_buf, size + (Py_ssize_t)t->frame_len) != 0)
        return 0;
    memcpy(PyByteArray_AS_STRING(out_buf) + size, t->frame, t->frame_len);
    return 1;
}

/* fw_tick's tick (see there): a new reference to True, None or the plant's read; NULL on an
   error (the plant's). */
static PyObject *one_tick(PyObject *emu, const int64_t *k)
{
    PyObject *x, *of, *u, *plant, *sensed, *pids = NULL, *buffer = NULL, *out_buf = NULL;
    PyObject *encoder = NULL, *entry = NULL, *enc;
    int64_t mode, last, tick_us, wd_ms;
    struct fw_tick t;
    int same, ok;
    if (!int_attr(emu, s_mode, 1LL << 30, &mode) || mode != k[0] ||
        !int_attr(emu, s_tick, TICK_MASK, &t.tick) || t.tick < 0 ||
        !int_attr(emu, s_last_host_tick, TICK_MASK, &last) || last < 0 ||
        !int_attr(emu, s_tick_us, 1LL << 30, &tick_us) || tick_us < 0 ||
        !int_attr(emu, s_watchdog_ms, 1LL << 62, &wd_ms))
        Py_RETURN_NONE;
    t.tick = (t.tick + 1) & TICK_MASK;
    if (((t.tick - last) & TICK_MASK) * tick_us / 1000 >= wd_ms) /* the watchdog trips */
        Py_RETURN_NONE;
    x = get_attr(emu, s_applied_mv);
    of = get_attr(emu, s_applied_of);
    same = x != NULL && x == of && x != Py_None;
    Py_XDECREF(x);
    Py_XDECREF(of);
    PyErr_Clear();
    if (!same)
        Py_RETURN_NONE;
    u = get_attr(emu, s_applied_v);
    plant = u == NULL ? NULL : get_attr(emu, s_read_plant);
    sensed = plant == NULL ? NULL : PyObject_CallFunctionObjArgs(plant, u, NULL);
    Py_XDECREF(u);
    Py_XDECREF(plant);
    if (sensed == NULL)
        return NULL;
    pids = typed_attr(emu, s_pids, &PyList_Type);
    buffer = get_attr(emu, s_buffer);
    out_buf = typed_attr(emu, s_out, &PyByteArray_Type);
    enc = get_attr(emu, s_encoder);
    encoder = enc == NULL ? NULL : PyObject_GenericGetDict(enc, NULL);
    Py_XDECREF(enc);
    PyErr_Clear();
    ok = pids != NULL && buffer != NULL &&
         fw_plan(emu, k, sensed, pids, buffer, out_buf, encoder, &t, &entry);
    if (!ok && PyErr_Occurred()) { /* an error a Python path would not meet: its own path */
        PyErr_Clear();
    }
    if (ok && !fw_commit(emu, sensed, pids, buffer, out_buf, encoder, &t, entry)) {
        Py_CLEAR(sensed);
    } else if (ok) {
        Py_DECREF(sensed);
        sensed = Py_True;
        Py_INCREF(sensed);
    }
    Py_XDECREF(entry);
    Py_XDECREF(pids);
    Py_XDECREF(buffer);
    Py_XDECREF(out_buf);
    Py_XDECREF(encoder);
    return sensed;
}

/* The consts of fw_tick and fw_ticks into k; 0 when they are not 4 int64s. */
static int tick_consts(const char *kb, Py_ssize_t klen, int64_t *k)
{
    if (klen != 4 * (Py_ssize_t)sizeof *k)
        return 0;
    memcpy(k, kb, (size_t)klen);
    return 1;
}

/* fw_tick(emu, consts) -> True | None | (counts, volts, amps):
   the firmware emulator's whole tick (guardid.firmware.emulator.FirmwareEmulator.advance)
   in position mode: the plant's read (emu._read_plant of the voltages the previous C tick
   applied), the tick count, the setpoints due from the buffer, the PID, limit stop and
   PWM (pid_pwm), the status bits and the TELEMETRY frame (telemetry) into emu._out; True
   when done. None (nothing done) out of position mode, when the watchdog trips at this
   tick or the applied voltages were not the C tick's; the plant's read (nothing else
   done) when a value is not of the kind or range this path takes: the Python path takes
   the tick from there. consts: int64s position mode, underrun, watchdog, estop bits. */
static PyObject *py_fw_tick(PyObject *self, PyObject *args)
{
    PyObject *emu;
    const char *kb;
    Py_ssize_t klen;
    int64_t k[4];
    (void)self;
    if (!PyArg_ParseTuple(args, "O!y#", &PyDict_Type, &emu, &kb, &klen))
        return NULL;
    if (!tick_consts(kb, klen, k))
        Py_RETURN_NONE;
    return one_tick(emu, k);
}

/* fw_ticks(emu, consts, count) -> (done, None | (counts, volts, amps)):
   up to count ticks of fw_tick in a row: done, the ticks it did; it stops at the first
   that is not done, with None when that tick did nothing (the Python path runs it), or
   with its plant's read (the Python path takes that tick from there). */
static PyObject *py_fw_ticks(PyObject *self, PyObject *args)
{
    PyObject *emu, *got = NULL;
    const char *kb;
    Py_ssize_t klen, count, done = 0;
    int64_t k[4];
    (void)self;
    if (!PyArg_ParseTuple(args, "O!y#n", &PyDict_Type, &emu, &kb, &klen, &count))
        return NULL;
    if (tick_consts(kb, klen, k))
        for (; done < count; ++done) {
            got = one_tick(emu, k);
            if (got == NULL)
                return NULL;
            if (got != Py_True)
                break;
            Py_CLEAR(got);
        }
    if (got == NULL) {
        got = Py_None;
        Py_INCREF(got);
    }
    return Py_BuildValue("(nN)", done, got);
}

/* fw_setpoints(emu, frames, start, consts) -> index:
   the emulator's handling (FirmwareEmulator.receive, _on_setpoint, _on_setpoint_ff) of the
   frames of the list frames from index start on that are SETPOINT or SETPOINT_FF frames it
   queues: each one's entry appended to emu.buffer, emu._last_frame the last one's,
   emu._last_reply None; the index of the first frame not handled. emu: the emulator's
   __dict__. Stops (that frame left to the Python path) at a
   frame of another kind, a retry of the previous host frame while it has an answer, a
   frame answered by NAK (wrong joint count, e-stop, wrong mode, late, not after the last
   buffered one, buffer full, feedforward beyond the supply) or a value of another kind.
   consts: int64s SETPOINT id, SETPOINT_FF id, position mode, buffer depth, hold flag bit,
   joint count n, then the n supplies [mV]. */
static PyObject *py_fw_setpoints(PyObject *self, PyObject *args)
{
    PyObject *emu, *frames, *buffer = NULL, *last_frame = NULL, *last_reply = NULL, *x;
    PyObject *append = NULL;
    const char *kb;
    Py_ssize_t klen, nf, i, nb, n, start, done;
    int64_t k[6 + MAX_TICK_JOINTS], mode, now, last_tick = 0;
    int estop, ok = 1, failed = 0;
    (void)self;
    if (!PyArg_ParseTuple(args, "O!O!ny#", &PyDict_Type, &emu, &PyList_Type, &frames, &start,
                          &kb, &klen))
        return NULL;
    done = start;
    if (klen < 48 || klen > (Py_ssize_t)sizeof k || klen % 8)
        return PyLong_FromSsize_t(done);
    memcpy(k, kb, (size_t)klen);
    n = (Py_ssize_t)k[5];
    nf = PyList_GET_SIZE(frames);
    if (start < 0 || start >= nf || n < 1 || klen != 8 * (6 + n) ||
        !int_attr(emu, s_mode, 1LL << 30, &mode) || !int_attr(emu, s_tick, TICK_MASK, &now) ||
        now < 0 || !true_attr(emu, s_estop, &estop))
        goto out;
    buffer = get_attr(emu, s_buffer);
    last_frame = get_attr(emu, s_last_frame);
    last_reply = get_attr(emu, s_last_reply);
    nb = buffer == NULL ? -1 : PyObject_Length(buffer);
    if (last_frame == NULL || last_reply == NULL || nb < 0)
        goto out;
    if (nb > 0) { /* the last buffered entry's tick */
        PyObject *e = PySequence_GetItem(buffer, nb - 1);
        ok = e != NULL && PyTuple_Check(e) && PyTuple_GET_SIZE(e) >= 1 &&
             PyLong_Check(PyTuple_GET_ITEM(e, 0));
        last_tick = ok ? PyLong_AsLongLong(PyTuple_GET_ITEM(e, 0)) : 0;
        Py_XDECREF(e);
        if (!ok || last_tick < 0 || last_tick > TICK_MASK)
            goto out;
    }
    for (i = start; i < nf; ++i) {
        PyObject *frame = PyList_GET_ITEM(frames, i), *msg, *position, *entry, *list, *ff = NULL;
        int64_t id, tick, flags;
        Py_ssize_t size, j;
        if (!PyTuple_Check(frame) || PyTuple_GET_SIZE(frame) != 3 ||
            !PyLong_Check(PyTuple_GET_ITEM(frame, 0)))
            break;
        id = PyLong_AsLongLong(PyTuple_GET_ITEM(frame, 0));
        msg = PyTuple_GET_ITEM(frame, 2);
        size = id == k[0] ? 3 : id == k[1] ? 4 : 0;
        if (size == 0 || !PyTuple_Check(msg) || PyTuple_GET_SIZE(msg) != size)
            break;
        if (i == start && last_reply != Py_None) { /* a retry: answered again by Python */
            int eq = PyObject_RichCompareBool(frame, last_frame, Py_EQ);
            if (eq != 0)
                break;
        }
        position = PyTuple_GET_ITEM(msg, 2);
        if (!PyLong_Check(PyTuple_GET_ITEM(msg, 0)) || !PyLong_Check(PyTuple_GET_ITEM(msg, 1)) ||
            !PyTuple_Check(position))
            break;
        tick = PyLong_AsLongLong(PyTuple_GET_ITEM(msg, 0));
        flags = PyLong_AsLongLong(PyTuple_GET_ITEM(msg, 1));
        if (PyErr_Occurred() || tick < 0 || tick > TICK_MASK || PyTuple_GET_SIZE(position) != n ||
            estop || mode != k[2] || NOT_AFTER(tick, now) || (nb && NOT_AFTER(tick, last_tick)) ||
            nb >= k[3])
            break;
        if (size == 4) { /* SETPOINT_FF: each feedforward within its supply */
            PyObject *f = PyTuple_GET_ITEM(msg, 3);
            if (!PyTuple_Check(f) || PyTuple_GET_SIZE(f) != n)
                break;
            for (j = 0; j < n; ++j) {
                PyObject *o = PyTuple_GET_ITEM(f, j);
                int overflow = 0;
                long long mv = PyLong_Check(o) ? PyLong_AsLongLongAndOverflow(o, &overflow) : 0;
                if (!PyLong_Check(o) || overflow || mv > k[6 + j] || mv < -k[6 + j])
                    break;
            }
            if (j < n)
                break;
            ff = PySequence_List(f);
        }
        list = PySequence_List(position);
        entry = list == NULL || (size == 4 && ff == NULL) ? NULL : PyTuple_New(size);
        if (entry == NULL) {
            Py_XDECREF(list);
            Py_XDECREF(ff);
            failed = 1;
            goto out;
        }
        Py_INCREF(PyTuple_GET_ITEM(msg, 0));
        PyTuple_SET_ITEM(entry, 0, PyTuple_GET_ITEM(msg, 0));
        PyTuple_SET_ITEM(entry, 1, list);
        x = flags & k[4] ? Py_True : Py_False;
        Py_INCREF(x);
        PyTuple_SET_ITEM(entry, 2, x);
        if (size == 4)
            PyTuple_SET_ITEM(entry, 3, ff);
        if (append == NULL)
            append = PyObject_GetAttr(buffer, s_append);
        x = append == NULL ? NULL : PyObject_CallFunctionObjArgs(append, entry, NULL);
        Py_DECREF(entry);
        failed = x == NULL;
        Py_XDECREF(x);
        if (failed)
            goto out;
        nb += 1;
        last_tick = tick;
        done = i + 1;
    }
out:
    if (!failed) {
        PyErr_Clear(); /* a value this path does not take: the Python path meets it */
        /* the last frame queued is the previous host frame, unanswered (after an error
           raised, the frames before it stay queued, as the handlers leave them) */
        if (done > start && (set_attr(emu, s_last_frame, PyList_GET_ITEM(frames, done - 1)) ||
                             set_attr(emu, s_last_reply, Py_None)))
            failed = 1;
    }
    Py_XDECREF(append);
    Py_XDECREF(buffer);
    Py_XDECREF(last_frame);
    Py_XDECREF(last_reply);
    if (failed)
        return NULL;
    return PyLong_FromSsize_t(done);
}

static PyMethodDef methods[] = {
    {"encode", py_encode, METH_VARARGS, "One wire frame from flattened values, or None."},
    {"encode_rows", py_encode_rows, METH_VARARGS, "Streamed setpoint frames from rows."},
    {"scan", py_scan, METH_VARARGS, "The leading valid frames of one kind in a chunk."},
    {"pid_pwm", py_pid_pwm, METH_VARARGS, "The firmware emulator's position-mode tick."},
    {"telemetry", py_telemetry, METH_VARARGS, "The firmware emulator's TELEMETRY frame."},
    {"fw_tick", py_fw_tick, METH_VARARGS, "The firmware emulator's position-mode tick."},
    {"fw_ticks", py_fw_ticks, METH_VARARGS, "Position-mode ticks of fw_tick in a row."},
    {"fw_setpoints", py_fw_setpoints, METH_VARARGS, "The emulator's queued setpoint frames."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "gp_pyext", "The protocol's C codec for the host's hot paths.", -1,
    methods, NULL, NULL, NULL, NULL,
};

static int intern_names(void)
{
    struct {
        PyObject **slot;
        const char *name;
    } names[] = {
        {&s_mode, "mode"}, {&s_applied_mv, "applied_mv"}, {&s_applied_of, "_applied_of"},
        {&s_applied_v, "_applied_v"}, {&s_tick, "tick"}, {&s_last_host_tick, "last_host_tick"},
        {&s_tick_us, "tick_us"}, {&s_watchdog_ms, "watchdog_ms"}, {&s_read_plant, "_read_plant"},
        {&s_buffer, "buffer"}, {&s_setpoint, "setpoint"}, {&s_setpoint_hold, "setpoint_hold"},
        {&s_feedforward_mv, "feedforward_mv"}, {&s_no_feedforward, "_no_feedforward"},
        {&s_pids, "pids"}, {&s_drives, "_drives"}, {&s_watchdog_tripped, "watchdog_tripped"},
        {&s_estop, "estop"}, {&s_streaming, "streaming"}, {&s_decimation, "decimation"},
        {&s_encoder, "encoder"}, {&s_seq, "seq"}, {&s_telemetry_cfg, "_telemetry_cfg"},
        {&s_out, "_out"}, {&s_counts, "counts"}, {&s_status, "status"},
        {&s_popleft, "popleft"}, {&s_append, "append"}, {&s_last_frame, "_last_frame"},
        {&s_last_reply, "_last_reply"},
    };
    size_t i;
    for (i = 0; i < sizeof names / sizeof names[0]; ++i) {
        *names[i].slot = PyUnicode_InternFromString(names[i].name);
        if (*names[i].slot == NULL)
            return 0;
    }
    return 1;
}

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
    if (!intern_names())
        return NULL;
    return PyModule_Create(&module);
}
