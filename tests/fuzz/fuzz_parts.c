/* The daemon's multipart part handling (server/api/smd_parts.c) driven
 * directly, without libmicrohttpd: the input is a script of the calls the
 * PostProcessor makes to smd_parts_on_part, so the fuzzer chooses the
 * part names, transfer encodings, the chunking of each part's data and
 * the offsets (a repeated name restarting at offset 0, empty chunks).
 * fuzz_multipart runs the real PostProcessor on multipart bodies; this
 * target covers the callbacks at a much higher rate (no HTTP, no
 * sockets), with the same outcome check (fuzz_parts_check.h).
 *
 * Each call is: a byte [key:3 | encoding:3 | restart:1 | kind:1], a
 * 16-bit little-endian chunk size (cut to what is left), the chunk.  key
 * 0-4 is a part name (the next byte modulo the number of parts picks
 * it), 5 none (NULL), 6 the same as the previous call, 7 a name taken
 * from the input (a length byte, then the bytes).  encoding
 * 0 is none, 1-4 binary, 7BIT, 8bit, base64, 5 one from the input (a
 * length byte, then the bytes), 6-7 none.  restart gives offset 0; else
 * the offset continues the previous call's part.  The script stops when
 * the callback answers MHD_NO, as the PostProcessor does. */
#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fuzz_parts_check.h"
#include "base/smd_util.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static const char *dir_;

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc, (void)argv;
    dir_ = fuzz_parts_upload_dir("parts");
    char inputs[128];
    if (snprintf(inputs, sizeof inputs, "%s/inputs", dir_) >= (int)sizeof inputs ||
        mkdir(inputs, 0700) != 0)
        abort();
    return 0;
}

typedef struct script {
    const uint8_t *p;
    size_t left;
} script;

/* A length byte then that many bytes, as a NUL-terminated string in buf
 * (NUL bytes of the input kept: the string is cut there). */
static const char *take_string(script *s, char *buf, size_t cap)
{
    size_t n = s->left ? s->p[0] : 0;
    if (s->left) {
        s->p++;
        s->left--;
    }
    if (n > s->left)
        n = s->left;
    if (n > cap - 1)
        n = cap - 1;
    memcpy(buf, s->p, n);
    buf[n] = '\0';
    s->p += n;
    s->left -= n;
    return buf;
}

/* prev: the previous call's key (NULL: none). */
static const char *take_key(script *s, int sel, const char *prev, char *buf, size_t cap)
{
    if (sel < 5) {
        unsigned pick = s->left ? s->p[0] : 0; /* one byte: which part */
        if (s->left) {
            s->p++;
            s->left--;
        }
        return sm_part_names[pick % SM_NPARTS];
    }
    if (sel == 5)
        return NULL;
    if (sel == 6)
        return prev;
    return take_string(s, buf, cap);
}

static const char *take_encoding(script *s, int sel, char *buf, size_t cap)
{
    static const char *const known[] = {NULL, "binary", "7BIT", "8bit", "base64"};
    if (sel < 5)
        return known[sel];
    if (sel == 5)
        return take_string(s, buf, cap);
    return NULL;
}

/* Runs the script's calls until it ends or the callback says MHD_NO. */
static void run_script(smd_parts *parts, script *s)
{
    char keybuf[80], prevbuf[80], tebuf[80];
    const char *prev = NULL;
    uint64_t off = 0;
    size_t last = 0;
    while (s->left >= 3) {
        uint8_t op = s->p[0];
        size_t n = (size_t)s->p[1] | (size_t)s->p[2] << 8;
        s->p += 3;
        s->left -= 3;
        const char *key = take_key(s, op & 7, prev, keybuf, sizeof keybuf);
        const char *te = take_encoding(s, op >> 3 & 7, tebuf, sizeof tebuf);
        int same = (!key && !prev) || (key && prev && strcmp(key, prev) == 0);
        off = op & 0x40 || !same ? 0 : off + last;
        if (n > s->left)
            n = s->left;
        enum MHD_ValueKind kind = op & 0x80 ? MHD_GET_ARGUMENT_KIND : MHD_POSTDATA_KIND;
        enum MHD_Result rc = smd_parts_on_part(parts, kind, key, "f.mesh", "text/plain", te,
                                               (const char *)s->p, off, n);
        s->p += n;
        s->left -= n;
        last = n;
        if (key && key != prevbuf)
            snprintf(prevbuf, sizeof prevbuf, "%s", key);
        prev = key ? prevbuf : NULL;
        if (rc != MHD_YES)
            break;
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    smd_parts parts;
    smd_parts_init(&parts, dir_);
    script s = {data, size};
    run_script(&parts, &s);
    fuzz_parts_finish(&parts);
    fuzz_parts_check(&parts);
    smd_parts_release(&parts);
    /* inputs/ stays between runs: the parts layer makes its files under
     * the names in path[] (open_part, then the rename), so removing those
     * leaves it empty, and a file left over would show as a 507 */
    for (int i = 0; i < SM_PART_PARAMS; i++)
        if (parts.seen[i] && parts.path[i][0])
            unlink(parts.path[i]);
    return 0;
}
