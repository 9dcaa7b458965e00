#include "util_gmsh.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include "shapematch/sm_io.h"

static int ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), k = strlen(suffix);
    return n >= k && strcmp(s + n - k, suffix) == 0;
}

static int write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    if (!f)
        return -1;
    size_t len = strlen(text);
    int ok = fwrite(text, 1, len, f) == len;
    return (fclose(f) == 0 && ok) ? 0 : -1;
}

/* Copies the last part of a log file into msg after prefix. */
static void tail_of_log(const char *log_path, const char *prefix, char *msg, size_t msglen)
{
    char tail[400] = "";
    FILE *f = fopen(log_path, "r");
    if (f) {
        long end = 0;
        if (fseek(f, 0, SEEK_END) == 0 && (end = ftell(f)) > 0) {
            long start = end > (long)sizeof tail - 1 ? end - (long)sizeof tail + 1 : 0;
            if (fseek(f, start, SEEK_SET) == 0) {
                size_t got = fread(tail, 1, sizeof tail - 1, f);
                tail[got] = '\0';
            }
        }
        fclose(f);
    }
    snprintf(msg, msglen, "%s%s%s", prefix, tail[0] ? "; gmsh log ends with: " : "", tail);
}

/* dir must exist; geo, log and output file names are built inside it. */
static sm_status run_gmsh(const char *dir, const char *geo, int dim, double clmax,
                          const char *fmt, int binary, const char *out_path, char *msg,
                          size_t msglen)
{
    char geo_path[4200], log_path[4200], clmax_text[64];
    snprintf(geo_path, sizeof geo_path, "%s/input.geo", dir);
    snprintf(log_path, sizeof log_path, "%s/gmsh.log", dir);
    snprintf(clmax_text, sizeof clmax_text, "%.17g", clmax);
    if (dim != 2 && dim != 3) {
        snprintf(msg, msglen, "dimension %d is not 2 or 3", dim);
        return SM_ERR_INVALID;
    }
    const char *format = fmt ? fmt : ends_with(out_path, ".msh") ? "msh41" : "mesh";
    if (write_text(geo_path, geo) != 0) {
        snprintf(msg, msglen, "cannot write %s: %s", geo_path, strerror(errno));
        return SM_ERR_IO;
    }
    pid_t pid = fork();
    if (pid < 0) {
        snprintf(msg, msglen, "fork: %s", strerror(errno));
        return SM_ERR_IO;
    }
    if (pid == 0) {
        int fd = open(log_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd >= 0) {
            dup2(fd, STDOUT_FILENO);
            dup2(fd, STDERR_FILENO);
            close(fd);
        }
        execlp("gmsh", "gmsh", geo_path, dim == 2 ? "-2" : "-3", "-format", format, "-clmax",
               clmax_text, "-nt", "1", "-v", "2", "-o", out_path, binary ? "-bin" : (char *)NULL,
               (char *)NULL);
        _exit(127);
    }
    int status = 0;
    while (waitpid(pid, &status, 0) < 0) {
        if (errno != EINTR) {
            snprintf(msg, msglen, "waitpid: %s", strerror(errno));
            return SM_ERR_IO;
        }
    }
    struct stat sb;
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || stat(out_path, &sb) != 0 ||
        sb.st_size == 0) {
        char prefix[256];
        if (WIFEXITED(status) && WEXITSTATUS(status) == 127)
            snprintf(prefix, sizeof prefix, "cannot run gmsh (is it installed and on PATH?)");
        else
            snprintf(prefix, sizeof prefix, "gmsh failed (status %d) making %s", status, out_path);
        tail_of_log(log_path, prefix, msg, msglen);
        return SM_ERR_IO;
    }
    return SM_OK;
}

static int make_temp_dir(char *dir, size_t len)
{
    const char *tmp = getenv("TMPDIR");
    snprintf(dir, len, "%s/sm_gmsh_XXXXXX", tmp && *tmp ? tmp : "/tmp");
    return mkdtemp(dir) ? 0 : -1;
}

static void remove_temp_dir(const char *dir)
{
    static const char *const names[] = {"input.geo", "gmsh.log", "mesh.mesh", "mesh.msh"};
    char path[4200];
    for (size_t k = 0; k < sizeof names / sizeof names[0]; k++) {
        snprintf(path, sizeof path, "%s/%s", dir, names[k]);
        unlink(path);
    }
    rmdir(dir);
}

sm_status util_gmsh_write(const char *geo, int dim, double clmax, const char *out_path,
                          char *msg, size_t msglen)
{
    char dir[4096];
    if (make_temp_dir(dir, sizeof dir) != 0) {
        snprintf(msg, msglen, "mkdtemp %s: %s", dir, strerror(errno));
        return SM_ERR_IO;
    }
    sm_status st = run_gmsh(dir, geo, dim, clmax, NULL, 0, out_path, msg, msglen);
    remove_temp_dir(dir);
    return st;
}

sm_status util_gmsh_write_format(const char *geo, int dim, double clmax, const char *format,
                                 int binary, const char *out_path, char *msg, size_t msglen)
{
    char dir[4096];
    if (make_temp_dir(dir, sizeof dir) != 0) {
        snprintf(msg, msglen, "mkdtemp %s: %s", dir, strerror(errno));
        return SM_ERR_IO;
    }
    sm_status st = run_gmsh(dir, geo, dim, clmax, format, binary, out_path, msg, msglen);
    remove_temp_dir(dir);
    return st;
}

sm_status util_gmsh_mesh(const char *geo, int dim, double clmax, sm_mesh **out, char *msg,
                         size_t msglen)
{
    char dir[4096], mesh_path[4200];
    *out = NULL;
    if (make_temp_dir(dir, sizeof dir) != 0) {
        snprintf(msg, msglen, "mkdtemp %s: %s", dir, strerror(errno));
        return SM_ERR_IO;
    }
    snprintf(mesh_path, sizeof mesh_path, "%s/mesh.mesh", dir);
    sm_status st = run_gmsh(dir, geo, dim, clmax, NULL, 0, mesh_path, msg, msglen);
    if (st == SM_OK) {
        sm_error err;
        sm_error_clear(&err);
        st = sm_mesh_read(mesh_path, out, &err);
        if (st != SM_OK)
            snprintf(msg, msglen, "reading the gmsh output: %s", err.msg);
        else if ((*out)->dim != dim) {
            snprintf(msg, msglen, "gmsh output read as a %dD mesh, expected %dD", (*out)->dim, dim);
            sm_mesh_free(*out);
            *out = NULL;
            st = SM_ERR_FORMAT;
        }
    }
    remove_temp_dir(dir);
    return st;
}
