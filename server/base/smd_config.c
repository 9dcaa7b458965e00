/* Flags and SHAPEMATCH_* variables of shapematchd (see smd_config.h).
 * One table drives parsing, the environment and --help, so the three
 * cannot disagree. */
#include "base/smd_config.h"

#include <errno.h>
#include <limits.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/smd_log.h"
#include "base/smd_util.h"

typedef enum opt_kind { OPT_LISTEN, OPT_PATH, OPT_INT, OPT_UINT, OPT_SIZE, OPT_DURATION, OPT_LEVEL,
                        OPT_ORIGINS, OPT_URL, OPT_TEXT, OPT_ROLE, OPT_HOSTS } opt_kind;

typedef struct opt {
    const char *flag;     /* "--spool" */
    const char *env;      /* "SHAPEMATCH_SPOOL" */
    const char *metavar;
    opt_kind kind;
    size_t offset;        /* into smd_config */
    double lo, hi;        /* range for numbers */
    const char *help;
    const char *default_text;
} opt;

#define OFF(field) offsetof(smd_config, field)

static const opt options[] = {
    {"--listen", "SHAPEMATCH_LISTEN", "HOST:PORT", OPT_LISTEN, OFF(listen_host), 0, 0,
     "address and port to listen on ([::1]:8080 for IPv6; port 0 picks a free one)",
     "127.0.0.1:8080"},
    {"--spool", "SHAPEMATCH_SPOOL", "DIR", OPT_PATH, OFF(spool), 0, 0,
     "job store: one folder per job (created if missing)", "./spool"},
    {"--workers", "SHAPEMATCH_WORKERS", "N", OPT_INT, OFF(workers), 1, 1024,
     "worker processes running at the same time", "number of cores"},
    {"--tokens-file", "SHAPEMATCH_TOKENS_FILE", "FILE", OPT_PATH, OFF(tokens_file), 0, 0,
     "bearer tokens, one per line as TOKEN [TENANT [admin]] ('#' comments); requests "
     "without one get 401 (/healthz and /readyz stay open); tenants see their own jobs "
     "only, admins all; SIGHUP reloads it", "none: no authentication"},
    {"--tls-cert", "SHAPEMATCH_TLS_CERT", "FILE", OPT_PATH, OFF(tls_cert), 0, 0,
     "serve HTTPS (TLS 1.2 and 1.3) with this PEM certificate chain, leaf first; needs "
     "--tls-key; SIGHUP reloads both", "none: plain HTTP"},
    {"--tls-key", "SHAPEMATCH_TLS_KEY", "FILE", OPT_PATH, OFF(tls_key), 0, 0,
     "the PEM private key of --tls-cert", "none"},
    {"--max-upload", "SHAPEMATCH_MAX_UPLOAD", "BYTES", OPT_SIZE, OFF(max_upload), 1024, 1e15,
     "largest POST /v1/jobs body (K, M, G suffixes); larger ones get 413", "256M"},
    {"--max-inflated", "SHAPEMATCH_MAX_INFLATED", "BYTES", OPT_SIZE, OFF(max_inflated), 0, 1e15,
     "largest decompressed size of one gzip-compressed part; larger ones get 413 "
     "(0 = 4 x --max-upload)", "4 x --max-upload"},
    {"--max-vertices", "SHAPEMATCH_MAX_VERTICES", "N", OPT_SIZE, OFF(max_vertices), 0, 2e8,
     "most vertices a mesh or solution part may declare, and 256 times that the voxels of a "
     "target image; more get 413 before anything is allocated (0 = --memory-limit / 4096, 1M "
     "for 4G; 200M without a memory limit)",
     "--memory-limit / 4096"},
    {"--max-elements", "SHAPEMATCH_MAX_ELEMENTS", "N", OPT_SIZE, OFF(max_elements), 0, 2e8,
     "most elements (or facets) a mesh part may declare; more get 413 "
     "(0 = --memory-limit / 4096)", "--memory-limit / 4096"},
    {"--job-timeout", "SHAPEMATCH_JOB_TIMEOUT", "SECONDS", OPT_DURATION, OFF(job_timeout), 0, 1e9,
     "wall time a run may take before it is killed (s, m, h, d suffixes; 0 = none)", "1h"},
    {"--retention", "SHAPEMATCH_RETENTION", "SECONDS", OPT_DURATION, OFF(retention), 0, 1e12,
     "finished jobs are deleted this long after they end (0 = keep)", "7d"},
    {"--cpu-limit", "SHAPEMATCH_CPU_LIMIT", "SECONDS", OPT_DURATION, OFF(cpu_limit), 0, 1e9,
     "CPU time of one worker (RLIMIT_CPU; 0 = none)", "0"},
    {"--memory-limit", "SHAPEMATCH_MEMORY_LIMIT", "BYTES", OPT_SIZE, OFF(memory_limit), 0, 1e18,
     "address space of one worker (RLIMIT_AS; 0 = none; not applied by "
     "AddressSanitizer builds)", "4G"},
    {"--worker", "SHAPEMATCH_WORKER", "PATH", OPT_PATH, OFF(worker_path), 0, 0,
     "worker program", "shapematch-worker next to shapematchd"},
    {"--worker-threads", "SHAPEMATCH_WORKER_THREADS", "N", OPT_INT, OFF(worker_threads), 0, 1024,
     "OpenMP/BLAS threads of one worker (OMP_NUM_THREADS, OPENBLAS_NUM_THREADS); 0 = "
     "cores / workers, so that a full pool does not oversubscribe the machine", "0"},
    {"--http-threads", "SHAPEMATCH_HTTP_THREADS", "N", OPT_INT, OFF(http_threads), 1, 64,
     "HTTP event-loop threads (epoll each)", "2 to 4, from the cores"},
    {"--max-connections", "SHAPEMATCH_MAX_CONNECTIONS", "N", OPT_UINT, OFF(max_connections), 1, 100000,
     "open connections in total (event followers included)", "1000"},
    {"--max-connections-per-ip", "SHAPEMATCH_MAX_CONNECTIONS_PER_IP", "N", OPT_UINT,
     OFF(max_connections_per_ip), 1, 100000, "open connections from one client address", "200"},
    {"--connection-timeout", "SHAPEMATCH_CONNECTION_TIMEOUT", "SECONDS", OPT_UINT,
     OFF(connection_timeout), 1, 86400,
     "a connection idle this long (e.g. a half-sent request) is closed; "
     "event streams waiting for events are exempt", "60"},
    {"--connection-memory", "SHAPEMATCH_CONNECTION_MEMORY", "BYTES", OPT_SIZE,
     OFF(connection_memory), 16384, 16777216,
     "memory pool of one connection (request line, headers, send buffer)", "64K"},
    {"--shutdown-grace", "SHAPEMATCH_SHUTDOWN_GRACE", "SECONDS", OPT_DURATION, OFF(shutdown_grace),
     0, 86400, "on SIGTERM/SIGINT, how long running jobs may finish before they "
     "are stopped and kept queued for the next start", "10s"},
    {"--keepalive", "SHAPEMATCH_KEEPALIVE", "SECONDS", OPT_DURATION, OFF(keepalive), 0.1, 3600,
     "idle event streams get a keepalive (SSE comment / empty NDJSON line)", "15s"},
    {"--kill-grace", "SHAPEMATCH_KILL_GRACE", "SECONDS", OPT_DURATION, OFF(kill_grace), 0, 3600,
     "delay between SIGTERM and SIGKILL when a worker is stopped", "5s"},
    {"--log-level", "SHAPEMATCH_LOG_LEVEL", "LEVEL", OPT_LEVEL, OFF(log_level), 0, 0,
     "debug, info (one line per request and job change), warn or error", "info"},
    {"--cors-origin", "SHAPEMATCH_CORS_ORIGINS", "ORIGIN", OPT_ORIGINS, OFF(cors_origins), 0, 0,
     "a web origin (https://app.example.org) whose pages may call the API; repeatable "
     "(the variable: comma-separated); '*' for any, only without --tokens-file.  POST and "
     "DELETE from other origins get 403", "none"},
    {"--public-url", "SHAPEMATCH_PUBLIC_URL", "URL", OPT_URL, OFF(public_url), 0, 0,
     "the daemon's URL as browsers see it behind a reverse proxy "
     "(https://host/prefix): its origin counts as the daemon's own", "none: the Host header"},
    {"--allowed-host", "SHAPEMATCH_ALLOWED_HOSTS", "HOST", OPT_HOSTS, OFF(allowed_hosts), 0, 0,
     "a name the daemon is reached by (maps.example.org, or with :PORT); repeatable (the "
     "variable: comma-separated).  A request whose Host header is neither one of them, an IP "
     "address, localhost (or a name under it), the --listen host nor --public-url's host gets "
     "421 on every route but /healthz, /readyz and the web app's page (DNS rebinding); its "
     "origins count as the daemon's own for POST and DELETE", "none: the listen address, IP "
     "addresses, localhost and --public-url's host"},
    {"--database", "SHAPEMATCH_DATABASE_URL", "URL", OPT_TEXT, OFF(database), 0, SMD_DATABASE_URL_MAX,
     "PostgreSQL job store and queue shared by several nodes (libpq connection string or "
     "postgresql:// URI; sslmode, PGPASSWORD and ~/.pgpass are honoured); --spool is then "
     "local scratch", "none: the embedded spool and queue"},
    {"--database-password-file", "SHAPEMATCH_DATABASE_PASSWORD_FILE", "FILE", OPT_PATH,
     OFF(database_password_file), 0, 0, "the database password (first line of FILE)", "none"},
    {"--role", "SHAPEMATCH_ROLE", "ROLE", OPT_ROLE, OFF(role), 0, 0,
     "all, api (uploads, status, events, results) or worker (claims and runs jobs); api "
     "and worker need --database", "all"},
    {"--max-attempts", "SHAPEMATCH_MAX_ATTEMPTS", "N", OPT_INT, OFF(max_attempts), 1, 1000,
     "runs of one job whose worker node lost its lease (killed, cut off) before it fails", "3"},
    {"--lease", "SHAPEMATCH_LEASE", "SECONDS", OPT_DURATION, OFF(lease), 1, 3600,
     "how long a worker node holds a job without renewing it (renewed every third of it)",
     "30s"},
    {"--database-statement-timeout", "SHAPEMATCH_DATABASE_STATEMENT_TIMEOUT", "SECONDS",
     OPT_DURATION, OFF(db_statement_timeout), 0.1, 3600,
     "statement_timeout of every database session: a statement running longer is cancelled "
     "(the call fails, the node is unready until the database answers again)", "30s"},
    {"--database-lock-timeout", "SHAPEMATCH_DATABASE_LOCK_TIMEOUT", "SECONDS", OPT_DURATION,
     OFF(db_lock_timeout), 0.1, 3600,
     "lock_timeout of every database session: a statement waiting this long for a row "
     "another session holds fails (a DELETE answers 503)", "5s"},
    {"--database-idle-timeout", "SHAPEMATCH_DATABASE_IDLE_TIMEOUT", "SECONDS", OPT_DURATION,
     OFF(db_idle_timeout), 0.1, 3600,
     "idle_in_transaction_session_timeout of every database session: the server ends a "
     "session idle this long inside a transaction (a frozen node) and frees its row locks; "
     "keep it below --lease", "15s"},
    {"--outbox-max", "SHAPEMATCH_OUTBOX_MAX", "BYTES", OPT_SIZE, OFF(outbox_max), 1 << 20, 1e15,
     "with --database: the events and results a node could not store in the database wait "
     "in SPOOL/outbox/ (replayed at the next start) up to this much; past it they wait in "
     "memory only, the node unready saying so", "256M"},
    {"--max-body-memory", "SHAPEMATCH_MAX_BODY_MEMORY", "BYTES", OPT_SIZE, OFF(max_body_memory),
     1 << 20, 1e15, "request bodies held in memory at once, all connections together (OGC "
     "execute requests and warp bodies, each at most 64M, batch descriptions); past it a "
     "request gets 503", "256M"},
    {"--body-stall-timeout", "SHAPEMATCH_BODY_STALL_TIMEOUT", "SECONDS", OPT_DURATION,
     OFF(body_stall_timeout), 0.5, 3600, "a request body (an upload) that brings no byte for "
     "this long is cut, however much it sent before", "10s"},
    {"--max-streams-per-ip", "SHAPEMATCH_MAX_STREAMS_PER_IP", "N", OPT_UINT,
     OFF(max_streams_per_ip), 0, 100000, "event streams and request bodies in progress (uploads) "
     "from one client address (an IPv6 client per /64, an IPv4 one per --submit-ipv4-prefix "
     "network); a new stream then ends that address's oldest, a body gets 503 (all addresses "
     "together: --max-connections minus --reserved-connections, where a new stream ends the "
     "oldest of the address most over its fair share, never one within it; 0 = only that)",
     "150"},
    {"--submit-rate", "SHAPEMATCH_SUBMIT_RATE", "N", OPT_UINT, OFF(submit_rate), 0, 1000000,
     "job submissions one tenant (one client address without --tokens-file) may make per "
     "--submit-window; more get 429 with Retry-After (0 = no limit)", "600"},
    {"--submit-window", "SHAPEMATCH_SUBMIT_WINDOW", "SECONDS", OPT_DURATION, OFF(submit_window), 1,
     86400, "the window of --submit-rate", "1m"},
    {"--submit-ipv4-prefix", "SHAPEMATCH_SUBMIT_IPV4_PREFIX", "BITS", OPT_UINT,
     OFF(submit_ipv4_prefix), 8, 32, "without --tokens-file, IPv4 clients share --submit-rate "
     "and --max-queued per network of this prefix (24: one per /24, as IPv6 clients share "
     "one per /64); the default, 32, is one per address, because a /24 often holds unrelated "
     "users (a campus, a carrier NAT pool, a cloud range) who would throttle each other, "
     "while IPv4 addresses are scarce enough that one client rarely holds many", "32"},
    {"--max-queued", "SHAPEMATCH_MAX_QUEUED", "N", OPT_UINT, OFF(max_queued), 0, 1000000,
     "unfinished jobs (accepted, queued or running) one tenant (one client address without "
     "--tokens-file) may have; more submissions get 429 with Retry-After (0 = no limit)", "1000"},
    {"--max-batch-targets", "SHAPEMATCH_MAX_BATCH_TARGETS", "N", OPT_UINT, OFF(max_batch_targets),
     1, 1000, "target jobs one batch (POST /v1/batches) may group; more get 413 (each target "
     "is an upload of its own, within --max-upload)", "100"},
    {"--header-timeout", "SHAPEMATCH_HEADER_TIMEOUT", "SECONDS", OPT_DURATION, OFF(header_timeout),
     0.5, 3600, "a request's line and headers must arrive within this time of the connection's "
     "start (or of its previous request), however steadily they trickle; idle keep-alive "
     "connections are closed after it too", "10s"},
    {"--min-upload-rate", "SHAPEMATCH_MIN_UPLOAD_RATE", "BYTES", OPT_SIZE, OFF(min_upload_rate), 0,
     1e12, "a request body (an upload) slower than this many bytes per second on average, "
     "measured after --header-timeout, is cut (0 = no minimum)", "1K"},
    {"--reserved-connections", "SHAPEMATCH_RESERVED_CONNECTIONS", "N", OPT_UINT,
     OFF(reserved_connections), 0, 100000,
     "connections of --max-connections kept for short requests: once fewer are free, each new "
     "connection closes the oldest one still sending its headers after 1 s (0 = "
     "--max-connections / 10)", "--max-connections / 10"},
    {"--check-threads", "SHAPEMATCH_CHECK_THREADS", "N", OPT_INT, OFF(check_threads), 1, 64,
     "uploads whose acceptance check (parsing, limits, mesh checks) runs at the same time, "
     "each in a child process off the HTTP threads; one tenant (one client address without "
     "--tokens-file) runs at most N - 1 of them (1 when N is 1), the others wait, the client "
     "with the fewest running first", "2"},
    {"--check-timeout", "SHAPEMATCH_CHECK_TIMEOUT", "SECONDS", OPT_DURATION, OFF(check_timeout), 0.1,
     86400, "wall time the acceptance check of one upload may take; longer ones are stopped and "
     "refused with 422; an upload still waiting for a check after this long gets 503 with "
     "Retry-After", "1m"},
};

#define NOPTIONS (sizeof options / sizeof options[0])

int smd_default_workers(void)
{
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n < 1 ? 1 : (n > 1024 ? 1024 : (int)n);
}

/* The input bounds left at 0: a gzip part may inflate to 4 x the upload
 * limit; a worker needs roughly 4 KiB per template element or vertex
 * (the 3D run's factorization dominates), so --memory-limit / 4096 of
 * each (1M for the 4 GiB default), capped at the readers' 200M. */
static void derive_limits(smd_config *c)
{
    const uint64_t cap = 200000000;
    if (!c->max_inflated)
        c->max_inflated = c->max_upload > UINT64_MAX / 4 ? UINT64_MAX : 4 * c->max_upload;
    uint64_t from_memory = c->memory_limit ? c->memory_limit / 4096 : cap;
    if (from_memory > cap)
        from_memory = cap;
    if (from_memory < 1024)
        from_memory = 1024;
    if (!c->max_vertices)
        c->max_vertices = from_memory;
    if (!c->max_elements)
        c->max_elements = from_memory;
    if (!c->reserved_connections)
        c->reserved_connections = c->max_connections / 10;
    if (c->reserved_connections >= c->max_connections)
        c->reserved_connections = c->max_connections - 1;
}

static void set_defaults(smd_config *c)
{
    memset(c, 0, sizeof *c);
    strcpy(c->listen_host, "127.0.0.1");
    c->listen_port = 8080;
    strcpy(c->spool, "./spool");
    c->workers = smd_default_workers();
    c->max_upload = (uint64_t)256 << 20;
    c->job_timeout = 3600;
    c->retention = 7 * 86400;
    c->cpu_limit = 0;
    c->memory_limit = (uint64_t)4 << 30;
    c->http_threads = c->workers < 4 ? (c->workers < 2 ? 2 : c->workers) : 4;
    c->max_connections = 1000;
    c->max_connections_per_ip = 200;
    c->connection_timeout = 60;
    c->connection_memory = 64 << 10;
    c->shutdown_grace = 10;
    c->keepalive = 15;
    c->kill_grace = 5;
    c->log_level = SMD_LOG_INFO;
    c->max_attempts = 3;
    c->lease = 30;
    c->db_statement_timeout = 30;
    c->db_lock_timeout = 5;
    c->db_idle_timeout = 15;
    c->max_body_memory = (uint64_t)256 << 20;
    c->outbox_max = (uint64_t)256 << 20;
    c->body_stall_timeout = 10;
    c->max_streams_per_ip = 150;
    c->submit_rate = 600;
    c->submit_window = 60;
    c->submit_ipv4_prefix = 32;
    c->max_queued = 1000;
    c->max_batch_targets = 100;
    c->header_timeout = 10;
    c->min_upload_rate = 1024;
    c->check_threads = 2;
    c->check_timeout = 60;
}

/* "HOST:PORT", "[v6]:PORT" or ":PORT" (all interfaces). */
static int parse_listen(const char *text, smd_config *c)
{
    const char *colon;
    size_t hostlen;
    const char *host = text;
    if (text[0] == '[') {
        const char *close = strchr(text, ']');
        if (!close || close[1] != ':')
            return -1;
        host = text + 1;
        hostlen = (size_t)(close - host);
        colon = close + 1;
    } else {
        colon = strrchr(text, ':');
        if (!colon)
            return -1;
        hostlen = (size_t)(colon - text);
    }
    if (hostlen >= sizeof c->listen_host)
        return -1;
    char *end;
    errno = 0;
    if (!(colon[1] >= '0' && colon[1] <= '9'))
        return -1;
    unsigned long port = strtoul(colon + 1, &end, 10);
    if (errno || *end || port > 65535)
        return -1;
    memcpy(c->listen_host, host, hostlen);
    c->listen_host[hostlen] = '\0';
    if (hostlen == 0)
        strcpy(c->listen_host, "0.0.0.0");
    c->listen_port = (unsigned)port;
    return 0;
}

/* 0 when origin is "*" or an exact origin: http(s)://host[:port], no
 * path, query, user info or comma; -1 otherwise. */
static int origin_valid(const char *origin)
{
    if (strcmp(origin, "*") == 0)
        return 0;
    if (strncmp(origin, "http://", 7) != 0 && strncmp(origin, "https://", 8) != 0)
        return -1;
    const char *host = strstr(origin, "://") + 3;
    if (*host == '\0' || *host == ':' || strchr(host, '@'))
        return -1;
    for (const char *p = host; *p; p++)
        if ((unsigned char)*p <= 0x20 || (unsigned char)*p >= 0x7f || strchr("/?#,@", *p))
            return -1;
    return 0;
}

/* Appends the comma-separated origins of value to c->cors_origins. */
static int add_origins(smd_config *c, const char *value, const char *source, char *msg, size_t cap)
{
    const char *p = value;
    for (;;) {
        size_t n = strcspn(p, ",");
        while (n > 0 && (*p == ' ' || *p == '\t')) {
            p++;
            n--;
        }
        size_t k = n;
        while (k > 0 && (p[k - 1] == ' ' || p[k - 1] == '\t'))
            k--;
        char origin[SMD_ORIGIN_MAX];
        if (k == 0 || k >= sizeof origin) {
            snprintf(msg, cap, "%s: expected origins like https://app.example.org, got '%s'", source, value);
            return -1;
        }
        memcpy(origin, p, k);
        origin[k] = '\0';
        if (origin_valid(origin) != 0) {
            snprintf(msg, cap, "%s: '%s' is not an origin (scheme://host[:port], no path) nor '*'",
                     source, origin);
            return -1;
        }
        if (c->ncors_origins == SMD_CORS_ORIGINS_MAX) {
            snprintf(msg, cap, "%s: at most %d origins", source, SMD_CORS_ORIGINS_MAX);
            return -1;
        }
        strcpy(c->cors_origins[c->ncors_origins++], origin);
        if (p[n] == '\0')
            return 0;
        p += n + 1;
    }
}

/* "name", "name:port", "[v6]" or "[v6]:port": letters, digits, '.', '-'. */
static int host_valid(const char *h)
{
    size_t n = strlen(h), end = n;
    if (h[0] == '[') {
        const char *close = strchr(h, ']');
        if (!close || close == h + 1 || strspn(h + 1, "0123456789abcdefABCDEF:.") != (size_t)(close - h - 1))
            return -1;
        end = (size_t)(close - h) + 1;
    } else {
        end = strcspn(h, ":");
        if (end == 0 || strspn(h, "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789.-") != end)
            return -1;
    }
    if (end == n)
        return 0;
    const char *port = h + end + 1;
    return h[end] == ':' && port[0] && strlen(port) <= 5 && strspn(port, "0123456789") == strlen(port)
               ? 0 : -1;
}

static int add_hosts(smd_config *c, const char *value, const char *source, char *msg, size_t cap)
{
    const char *p = value;
    for (;;) {
        size_t n = strcspn(p, ","), k = n;
        char host[SMD_ORIGIN_MAX];
        while (k > 0 && (*p == ' ' || *p == '\t')) {
            p++;
            n--;
            k--;
        }
        while (k > 0 && (p[k - 1] == ' ' || p[k - 1] == '\t'))
            k--;
        if (k == 0 || k >= sizeof host) {
            snprintf(msg, cap, "%s: expected host names like maps.example.org, got '%s'", source, value);
            return -1;
        }
        memcpy(host, p, k);
        host[k] = '\0';
        if (host_valid(host) != 0) {
            snprintf(msg, cap, "%s: '%s' is not a host name (name[:port], [v6][:port])", source, host);
            return -1;
        }
        if (c->nallowed_hosts == SMD_ALLOWED_HOSTS_MAX) {
            snprintf(msg, cap, "%s: at most %d hosts", source, SMD_ALLOWED_HOSTS_MAX);
            return -1;
        }
        strcpy(c->allowed_hosts[c->nallowed_hosts++], host);
        if (p[n] == '\0')
            return 0;
        p += n + 1;
    }
}

/* One parser per kind of value (the table's rows name their kind): each
 * bounds the text before it converts or copies anything, and names
 * source (the flag or variable) in msg when it refuses. */
typedef int (*opt_parser)(smd_config *c, const opt *o, const char *value, const char *source,
                          char *msg, size_t cap);

static int refuse(char *msg, size_t cap, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static int refuse(char *msg, size_t cap, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, cap, fmt, ap);
    va_end(ap);
    return -1;
}

static char *field_of(smd_config *c, const opt *o)
{
    return (char *)c + o->offset;
}

static int parse_listen_opt(smd_config *c, const opt *o, const char *value, const char *source,
                            char *msg, size_t cap)
{
    (void)o;
    if (parse_listen(value, c) != 0)
        return refuse(msg, cap, "%s: expected HOST:PORT (e.g. 127.0.0.1:8080), got '%s'", source,
                      value);
    return 0;
}

/* OPT_PATH (limit PATH_MAX), OPT_TEXT (limit o->hi), OPT_URL (an http(s)
 * URL within SMD_ORIGIN_MAX) */
static int parse_text(smd_config *c, const opt *o, const char *value, const char *source,
                      char *msg, size_t cap)
{
    size_t limit = o->kind == OPT_PATH ? PATH_MAX : o->kind == OPT_URL ? SMD_ORIGIN_MAX
                                                                       : (size_t)o->hi;
    int url_ok = strncmp(value, "http://", 7) == 0 || strncmp(value, "https://", 8) == 0;
    if (o->kind == OPT_URL && (strlen(value) >= limit || !url_ok))
        return refuse(msg, cap, "%s: expected an http:// or https:// URL (at most %zu bytes), got "
                      "'%s'", source, limit - 1, value);
    if (strlen(value) >= limit && o->kind == OPT_PATH)
        return refuse(msg, cap, "%s: path too long", source);
    if (strlen(value) >= limit)
        return refuse(msg, cap, "%s: at most %zu bytes", source, limit - 1);
    strcpy(field_of(c, o), value);
    return 0;
}

static int parse_integer(smd_config *c, const opt *o, const char *value, const char *source,
                         char *msg, size_t cap)
{
    /* the bounded parser: digits only, no overflow whatever the length
     * (every integer row is >= 0) */
    uint64_t v;
    if (smd_parse_uint(value, (uint64_t)o->lo, (uint64_t)o->hi, &v) != SMD_NUM_OK)
        return refuse(msg, cap, "%s: expected an integer in [%.0f, %.0f], got '%s'", source, o->lo,
                      o->hi, value);
    if (o->kind == OPT_INT)
        *(int *)field_of(c, o) = (int)v;
    else
        *(unsigned *)field_of(c, o) = (unsigned)v;
    return 0;
}

static int parse_size_opt(smd_config *c, const opt *o, const char *value, const char *source,
                          char *msg, size_t cap)
{
    uint64_t v;
    if (smd_parse_size(value, &v) != 0 || (double)v < o->lo || (double)v > o->hi)
        return refuse(msg, cap, "%s: expected a size in bytes (K, M, G suffixes) in [%.0f, %.0f], "
                      "got '%s'", source, o->lo, o->hi, value);
    *(uint64_t *)field_of(c, o) = v;
    return 0;
}

static int parse_duration_opt(smd_config *c, const opt *o, const char *value, const char *source,
                              char *msg, size_t cap)
{
    double v;
    if (smd_parse_duration(value, &v) != 0 || v < o->lo || v > o->hi)
        return refuse(msg, cap, "%s: expected a duration in seconds (s, m, h, d suffixes) in [%g, "
                      "%g], got '%s'", source, o->lo, o->hi, value);
    *(double *)field_of(c, o) = v;
    return 0;
}

static int parse_origins_opt(smd_config *c, const opt *o, const char *value, const char *source,
                             char *msg, size_t cap)
{
    (void)o;
    return add_origins(c, value, source, msg, cap);
}

static int parse_hosts_opt(smd_config *c, const opt *o, const char *value, const char *source,
                           char *msg, size_t cap)
{
    (void)o;
    return add_hosts(c, value, source, msg, cap);
}

static int parse_role(smd_config *c, const opt *o, const char *value, const char *source,
                      char *msg, size_t cap)
{
    static const char *const roles[] = {"all", "api", "worker"};
    for (int i = 0; i < 3; i++)
        if (strcmp(value, roles[i]) == 0) {
            *(int *)field_of(c, o) = i;
            return 0;
        }
    return refuse(msg, cap, "%s: expected all, api or worker, got '%s'", source, value);
}

static int parse_level(smd_config *c, const opt *o, const char *value, const char *source,
                       char *msg, size_t cap)
{
    int level = smd_log_level_from_name(value);
    if (level < 0)
        return refuse(msg, cap, "%s: expected debug, info, warn or error, got '%s'", source, value);
    *(int *)field_of(c, o) = level;
    return 0;
}

static const opt_parser parsers[] = {
    [OPT_LISTEN] = parse_listen_opt, [OPT_PATH] = parse_text,       [OPT_INT] = parse_integer,
    [OPT_UINT] = parse_integer,      [OPT_SIZE] = parse_size_opt,   [OPT_DURATION] = parse_duration_opt,
    [OPT_LEVEL] = parse_level,       [OPT_ORIGINS] = parse_origins_opt, [OPT_URL] = parse_text,
    [OPT_TEXT] = parse_text,         [OPT_ROLE] = parse_role,       [OPT_HOSTS] = parse_hosts_opt,
};

static int apply(smd_config *c, const opt *o, const char *value, const char *source,
                 char *msg, size_t cap)
{
    return parsers[o->kind](c, o, value, source, msg, cap);
}

int smd_config_number_at(size_t i, smd_config_number *out)
{
    for (size_t k = 0; k < sizeof options / sizeof options[0]; k++) {
        const opt *o = &options[k];
        int integer = o->kind == OPT_INT || o->kind == OPT_UINT;
        if (!integer && o->kind != OPT_SIZE && o->kind != OPT_DURATION)
            continue;
        if (i-- > 0)
            continue;
        out->flag = o->flag;
        out->kind = integer ? SMD_CONFIG_INTEGER
                    : o->kind == OPT_SIZE ? SMD_CONFIG_SIZE : SMD_CONFIG_DURATION;
        out->lo = o->lo;
        out->hi = o->hi;
        out->width = o->kind == OPT_INT ? sizeof(int) : o->kind == OPT_UINT ? sizeof(unsigned)
                     : o->kind == OPT_SIZE ? sizeof(uint64_t) : sizeof(double);
        out->is_signed = o->kind == OPT_INT;
        return 1;
    }
    return 0;
}

smd_config_result smd_config_parse(smd_config *c, int argc, char **argv,
                                   smd_env_fn env, void *env_user, char *msg,
                                   size_t cap)
{
    set_defaults(c);
    msg[0] = '\0';
    for (size_t i = 0; env && i < NOPTIONS; i++) {
        const char *value = env(options[i].env, env_user);
        if (!value)
            continue;
        if (apply(c, &options[i], value, options[i].env, msg, cap) != 0)
            return SMD_CONFIG_ERROR;
    }
    int origins_from_flags = 0; /* the first --cors-origin replaces the variable's list */
    int hosts_from_flags = 0;   /* the same for --allowed-host */
    for (int a = 1; a < argc; a++) {
        const char *arg = argv[a];
        if (strcmp(arg, "-h") == 0 || strcmp(arg, "--help") == 0)
            return SMD_CONFIG_HELP;
        if (strcmp(arg, "--version") == 0)
            return SMD_CONFIG_VERSION;
        const char *eq = strchr(arg, '=');
        size_t namelen = eq ? (size_t)(eq - arg) : strlen(arg);
        const opt *o = NULL;
        for (size_t i = 0; i < NOPTIONS; i++)
            if (strlen(options[i].flag) == namelen && strncmp(options[i].flag, arg, namelen) == 0)
                o = &options[i];
        if (!o) {
            snprintf(msg, cap, "unknown option '%.*s' (see --help)", (int)namelen, arg);
            return SMD_CONFIG_ERROR;
        }
        const char *value;
        if (eq) {
            value = eq + 1;
        } else {
            if (a + 1 >= argc) {
                snprintf(msg, cap, "%s: missing value (%s)", o->flag, o->metavar);
                return SMD_CONFIG_ERROR;
            }
            value = argv[++a];
        }
        if (o->kind == OPT_ORIGINS && !origins_from_flags) {
            c->ncors_origins = 0;
            origins_from_flags = 1;
        }
        if (o->kind == OPT_HOSTS && !hosts_from_flags) {
            c->nallowed_hosts = 0;
            hosts_from_flags = 1;
        }
        if (apply(c, o, value, o->flag, msg, cap) != 0)
            return SMD_CONFIG_ERROR;
    }
    for (unsigned i = 0; i < c->ncors_origins; i++)
        if (c->tokens_file[0] && strcmp(c->cors_origins[i], "*") == 0) {
            snprintf(msg, cap, "--cors-origin: '*' is refused with --tokens-file "
                               "(list the origins of the pages that hold tokens)");
            return SMD_CONFIG_ERROR;
        }
    if (c->spool[0] == '\0') {
        snprintf(msg, cap, "--spool: must not be empty");
        return SMD_CONFIG_ERROR;
    }
    if (!c->tls_cert[0] != !c->tls_key[0]) {
        snprintf(msg, cap, "--tls-cert and --tls-key go together");
        return SMD_CONFIG_ERROR;
    }
    if (c->role != SMD_ROLE_ALL && !c->database[0]) {
        snprintf(msg, cap, "--role %s needs --database (nodes share jobs through PostgreSQL)",
                 c->role == SMD_ROLE_API ? "api" : "worker");
        return SMD_CONFIG_ERROR;
    }
    if (c->database_password_file[0] && !c->database[0]) {
        snprintf(msg, cap, "--database-password-file needs --database");
        return SMD_CONFIG_ERROR;
    }
    derive_limits(c);
    return SMD_CONFIG_OK;
}

void smd_config_help(FILE *out)
{
    fprintf(out,
            "Usage: shapematchd [OPTIONS]\n"
            "\n"
            "HTTP daemon of shapematch: accepts matching jobs (POST /v1/jobs, multipart\n"
            "upload of a template mesh, a target mesh, its distance field and JSON\n"
            "parameters), runs each in a worker process, streams progress\n"
            "(GET /v1/jobs/{id}/events) and serves the results.  Its API description is\n"
            "served at /v1/openapi.yaml (e.g. http://127.0.0.1:8080/v1/openapi.yaml).\n"
            "\n"
            "Options (each also read from the environment variable shown; a flag wins):\n");
    for (size_t i = 0; i < NOPTIONS; i++) {
        const opt *o = &options[i];
        fprintf(out, "  %s %s\n      %s\n      [env %s; default: %s]\n", o->flag, o->metavar, o->help,
                o->env, o->default_text);
    }
    fprintf(out,
            "  -h, --help      this text\n"
            "  --version       print the version\n"
            "\n"
            "Signals: SIGTERM/SIGINT stop gracefully (a second one stops at once).\n"
            "Logs: JSON lines on stderr.\n"
            "\n"
            "Examples:\n"
            "  # on this machine: port 8080, the jobs in ./spool, two workers; the web app\n"
            "  # at http://127.0.0.1:8080/\n"
            "  shapematchd --listen 127.0.0.1:8080 --spool spool --workers 2\n"
            "  # for other machines: tokens and TLS, finished jobs kept a month\n"
            "  shapematchd --listen 0.0.0.0:8443 --tokens-file tokens --tls-cert cert.pem \\\n"
            "      --tls-key key.pem --retention 30d\n"
            "  # one node of several on PostgreSQL (docs/cluster.md)\n"
            "  shapematchd --database postgresql://shapematch@db/shapematch --role api\n");
}
