/* The wire contract's FCS (CRC-16/X-25, docs/wire-format.md) in C, and the per-datagram steps around it.
 *
 * Part of the compiled cores (docs/architecture.md, "Compiled cores (mypyc)"; mlink_sim/_accel.py C_EXTENSIONS):
 * setup.py builds it next to mlink_sim/wire/fcs.py, which uses it when the compiled cores are selected and keeps
 * the pure-Python functions as the fallback. tests/wire/test_fcs_native.py pins every function here to the pure one,
 * byte for byte.
 *
 * Why by hand: the fast paths spend most of their byte work on the FCS (binascii.crc_hqx is the non-reflected
 * CRC, so X-25 costs a translated copy and a slice around it), and no maintained library computes X-25 and
 * seals, checks or patches a datagram in one call. The CRC is the table-driven reflected CRC (polynomial 0x8408,
 * init 0xFFFF, xorout 0xFFFF), four bytes per step ("slicing by 4"), checked against crc16_x25_reference.
 *
 *   crc16_x25(data) -> int                    the FCS of data (any bytes-like object)
 *   seal(body) -> bytes                       body + its FCS (u16 LE): wire.frame.with_fcs
 *   fcs_ok(datagram) -> bool                  the trailing FCS matches the bytes before it: wire.frame.fcs_ok
 *   patch_seal(template, cycle_at, cycle, wdt_at, wdt) -> bytes
 *                                             a copy of template with the u32 LE cycle at cycle_at and the byte
 *                                             wdt at wdt_at, sealed: the master's cyclic command
 *                                             (master.fastpath.CyclicFrames.command); template is not changed
 *   steady_delta(datagram, previous, cycle_at, wdt_at) -> int
 *                                             cycle | wdt << 32 when datagram differs from previous (as long)
 *                                             only in the u32 LE cycle at cycle_at, the byte at wdt_at and the
 *                                             FCS, and its FCS is right; else -1: the inverse of patch_seal, for
 *                                             the cyclic datagrams' steady state (wire.frame.steady_delta)
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>

/* Slicing by 4: table[0][b] is the register's change for byte b, table[k][b] for byte b followed by k zero
   bytes. Four bytes per step: the 16-bit register absorbs the first two, the other two enter fresh. */
static uint16_t table[4][256];

static void
make_table(void)
{
    for (unsigned i = 0; i < 256; i++) {
        uint16_t crc = (uint16_t)i;
        for (int bit = 0; bit < 8; bit++)
            crc = (crc & 1) ? (uint16_t)((crc >> 1) ^ 0x8408) : (uint16_t)(crc >> 1);
        table[0][i] = crc;
    }
    for (int k = 1; k < 4; k++)
        for (unsigned i = 0; i < 256; i++)
            table[k][i] = (uint16_t)((table[k - 1][i] >> 8) ^ table[0][table[k - 1][i] & 0xFF]);
}

static inline uint16_t
x25(const unsigned char *p, Py_ssize_t n)
{
    uint16_t crc = 0xFFFF;
    for (; n >= 4; n -= 4, p += 4) {
        crc ^= (uint16_t)(p[0] | (p[1] << 8));
        crc = (uint16_t)(table[3][crc & 0xFF] ^ table[2][crc >> 8] ^ table[1][p[2]] ^ table[0][p[3]]);
    }
    while (n-- > 0)
        crc = (uint16_t)((crc >> 8) ^ table[0][(crc ^ *p++) & 0xFF]);
    return (uint16_t)(crc ^ 0xFFFF);
}

/* A read-only view of obj's bytes: bytes and bytearray directly, anything else through the buffer protocol
   (released by release()). */
typedef struct {
    const unsigned char *p;
    Py_ssize_t n;
    Py_buffer view;
    int has_view;
} bytes_in;

static int
get_bytes(PyObject *obj, bytes_in *in)
{
    in->has_view = 0;
    if (PyBytes_CheckExact(obj)) {
        in->p = (const unsigned char *)PyBytes_AS_STRING(obj);
        in->n = PyBytes_GET_SIZE(obj);
        return 0;
    }
    if (PyByteArray_CheckExact(obj)) {
        in->p = (const unsigned char *)PyByteArray_AS_STRING(obj);
        in->n = PyByteArray_GET_SIZE(obj);
        return 0;
    }
    if (PyObject_GetBuffer(obj, &in->view, PyBUF_SIMPLE) < 0)
        return -1;
    in->has_view = 1;
    in->p = (const unsigned char *)in->view.buf;
    in->n = in->view.len;
    return 0;
}

static void
release(bytes_in *in)
{
    if (in->has_view)
        PyBuffer_Release(&in->view);
}

/* A new bytes object: n bytes of src (patched by the caller before sealing), then their FCS, u16 LE. */
static PyObject *
sealed_copy(const unsigned char *src, Py_ssize_t n, unsigned char **out)
{
    PyObject *result = PyBytes_FromStringAndSize(NULL, n + 2);
    if (result == NULL)
        return NULL;
    *out = (unsigned char *)PyBytes_AS_STRING(result);
    memcpy(*out, src, (size_t)n);
    return result;
}

static void
append_fcs(unsigned char *buf, Py_ssize_t n)
{
    uint16_t fcs = x25(buf, n);
    buf[n] = (unsigned char)(fcs & 0xFF);
    buf[n + 1] = (unsigned char)(fcs >> 8);
}

static PyObject *
fcsc_crc16_x25(PyObject *module, PyObject *data)
{
    bytes_in in;
    if (get_bytes(data, &in) < 0)
        return NULL;
    uint16_t crc = x25(in.p, in.n);
    release(&in);
    return PyLong_FromLong(crc);
}

static PyObject *
fcsc_seal(PyObject *module, PyObject *body)
{
    bytes_in in;
    unsigned char *buf;
    if (get_bytes(body, &in) < 0)
        return NULL;
    PyObject *result = sealed_copy(in.p, in.n, &buf);
    if (result != NULL)
        append_fcs(buf, in.n);
    release(&in);
    return result;
}

static PyObject *
fcsc_fcs_ok(PyObject *module, PyObject *datagram)
{
    bytes_in in;
    if (get_bytes(datagram, &in) < 0)
        return NULL;
    int ok = 0;
    if (in.n >= 2) {
        uint16_t fcs = (uint16_t)(in.p[in.n - 2] | (in.p[in.n - 1] << 8));
        ok = x25(in.p, in.n - 2) == fcs;
    }
    release(&in);
    return PyBool_FromLong(ok);
}

/* A non-negative integer argument of function fn that fits in limit (inclusive), or -1 with ValueError set. */
static long long
bounded_in(const char *fn, PyObject *arg, const char *name, unsigned long long limit)
{
    unsigned long long value = PyLong_AsUnsignedLongLong(arg);
    if (value == (unsigned long long)-1 && PyErr_Occurred()) {
        if (PyErr_ExceptionMatches(PyExc_OverflowError)) {
            PyErr_Clear();
            PyErr_Format(PyExc_ValueError, "%s: %s must be an int in 0..%llu", fn, name, limit);
        }
        return -1;
    }
    if (value > limit) {
        PyErr_Format(PyExc_ValueError, "%s: %s must be an int in 0..%llu", fn, name, limit);
        return -1;
    }
    return (long long)value;
}

static long long
bounded(PyObject *arg, const char *name, unsigned long long limit)
{
    return bounded_in("patch_seal", arg, name, limit);
}

static PyObject *
fcsc_patch_seal(PyObject *module, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 5) {
        PyErr_Format(PyExc_TypeError, "patch_seal() takes 5 arguments (%zd given)", nargs);
        return NULL;
    }
    bytes_in in;
    if (get_bytes(args[0], &in) < 0)
        return NULL;
    PyObject *result = NULL;
    unsigned char *buf;
    long long cycle_at = bounded(args[1], "cycle_at", 0xFFFFULL);
    long long cycle = cycle_at < 0 ? -1 : bounded(args[2], "cycle", 0xFFFFFFFFULL);
    long long wdt_at = cycle < 0 ? -1 : bounded(args[3], "wdt_at", 0xFFFFULL);
    long long wdt = wdt_at < 0 ? -1 : bounded(args[4], "wdt", 0xFF);
    if (wdt < 0)
        goto done;
    if (cycle_at + 4 > in.n || wdt_at >= in.n) {
        PyErr_Format(PyExc_ValueError, "patch_seal: offsets %lld (cycle) and %lld (wdt) outside a %zd-byte template",
                     cycle_at, wdt_at, in.n);
        goto done;
    }
    result = sealed_copy(in.p, in.n, &buf);
    if (result == NULL)
        goto done;
    for (int i = 0; i < 4; i++)
        buf[cycle_at + i] = (unsigned char)((cycle >> (8 * i)) & 0xFF);
    buf[wdt_at] = (unsigned char)wdt;
    append_fcs(buf, in.n);
done:
    release(&in);
    return result;
}

/* a and b are equal in their first n bytes but for the 4 bytes at c and the byte at w (both inside the n bytes):
   three memcmp over the stretches around the two holes (which may overlap), not a test per byte. */
static int
same_but(const unsigned char *a, const unsigned char *b, Py_ssize_t n, Py_ssize_t c, Py_ssize_t w)
{
    Py_ssize_t s1 = c, e1 = c + 4, s2 = w, e2 = w + 1;
    if (s2 < s1) {
        s1 = w; e1 = w + 1; s2 = c; e2 = c + 4;
    }
    if (s2 < e1) {  /* the holes overlap: one hole from s1 to the later end */
        e1 = e2 > e1 ? e2 : e1;
        s2 = e2 = e1;
    }
    return memcmp(a, b, (size_t)s1) == 0 && memcmp(a + e1, b + e1, (size_t)(s2 - e1)) == 0
           && memcmp(a + e2, b + e2, (size_t)(n - e2)) == 0;
}

static PyObject *
fcsc_steady_delta(PyObject *module, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 4) {
        PyErr_Format(PyExc_TypeError, "steady_delta() takes 4 arguments (%zd given)", nargs);
        return NULL;
    }
    long long cycle_at = bounded_in("steady_delta", args[2], "cycle_at", 0xFFFFULL);
    long long wdt_at = cycle_at < 0 ? -1 : bounded_in("steady_delta", args[3], "wdt_at", 0xFFFFULL);
    if (wdt_at < 0)
        return NULL;
    bytes_in now, before;
    if (get_bytes(args[0], &now) < 0)
        return NULL;
    if (get_bytes(args[1], &before) < 0) {
        release(&now);
        return NULL;
    }
    long long result = -1;
    PyObject *out = NULL;
    Py_ssize_t body = now.n - 2;  /* the bytes the FCS covers */
    if (now.n == before.n && now.n >= 2) {
        if (cycle_at + 4 > body || wdt_at >= body) {
            PyErr_Format(PyExc_ValueError,
                         "steady_delta: offsets %lld (cycle) and %lld (wdt) outside a %zd-byte datagram",
                         cycle_at, wdt_at, now.n);
            goto done;
        }
        if (same_but(now.p, before.p, body, (Py_ssize_t)cycle_at, (Py_ssize_t)wdt_at)
                && x25(now.p, body) == (uint16_t)(now.p[body] | (now.p[body + 1] << 8))) {
            const unsigned char *c = now.p + cycle_at;
            result = (long long)((uint32_t)c[0] | (uint32_t)c[1] << 8 | (uint32_t)c[2] << 16 | (uint32_t)c[3] << 24)
                     | (long long)now.p[wdt_at] << 32;
        }
    }
    out = PyLong_FromLongLong(result);
done:
    release(&now);
    release(&before);
    return out;
}

static PyMethodDef methods[] = {
    {"crc16_x25", fcsc_crc16_x25, METH_O, "CRC-16/X-25 of data (the FCS of the wire contract)."},
    {"seal", fcsc_seal, METH_O, "body + its FCS (u16 LE)."},
    {"fcs_ok", fcsc_fcs_ok, METH_O, "The datagram's trailing FCS (u16 LE) matches the bytes before it."},
    {"patch_seal", (PyCFunction)(void (*)(void))fcsc_patch_seal, METH_FASTCALL,
     "patch_seal(template, cycle_at, cycle, wdt_at, wdt): a sealed copy of template with the u32 LE cycle at "
     "cycle_at and the byte wdt at wdt_at."},
    {"steady_delta", (PyCFunction)(void (*)(void))fcsc_steady_delta, METH_FASTCALL,
     "steady_delta(datagram, previous, cycle_at, wdt_at): cycle | wdt << 32 when datagram differs from previous "
     "only in the u32 LE cycle at cycle_at, the byte at wdt_at and its FCS, which is right; else -1."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module_def = {
    PyModuleDef_HEAD_INIT, "_fcsc", "The wire contract's FCS in C (see mlink_sim/wire/fcs.py).", -1, methods,
};

PyMODINIT_FUNC
PyInit__fcsc(void)
{
    make_table();
    return PyModule_Create(&module_def);
}
