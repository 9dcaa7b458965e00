/* shapematchd configuration: command-line flags, each with a matching
 * SHAPEMATCH_* environment variable (for containers).  A flag wins over
 * its variable, the variable over the default.  `shapematchd --help`
 * prints the table below with the defaults. */
#ifndef SMD_CONFIG_H
#define SMD_CONFIG_H

#include <limits.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

/* Listed CORS origins at most, and the longest origin or public URL. */
#define SMD_CORS_ORIGINS_MAX 32
#define SMD_ORIGIN_MAX 256
#define SMD_DATABASE_URL_MAX 1024
#define SMD_ALLOWED_HOSTS_MAX 16

typedef struct smd_config {
    char listen_host[256];        /* --listen HOST:PORT (IPv6 as [::1]:8080) */
    unsigned listen_port;         /* 0 = any free port (printed in the log) */
    char spool[PATH_MAX];         /* --spool DIR */
    int workers;                  /* --workers N: concurrent worker processes */
    char tokens_file[PATH_MAX];   /* --tokens-file FILE ("" = no auth) */
    char tls_cert[PATH_MAX];      /* --tls-cert FILE: PEM chain ("" = plain HTTP) */
    char tls_key[PATH_MAX];       /* --tls-key FILE: PEM key (with --tls-cert) */
    uint64_t max_upload;          /* --max-upload BYTES: whole request body */
    uint64_t max_inflated;        /* --max-inflated: decompressed bytes of one
                                   * .gz part (0 given: 4 x --max-upload) */
    uint64_t max_vertices;        /* --max-vertices, --max-elements: declared */
    uint64_t max_elements;        /* counts of one part (0 given: from
                                   * --memory-limit, see smd_config_limits) */
    double job_timeout;           /* --job-timeout: wall time per run, 0 = none */
    double retention;             /* --retention: keep finished jobs, 0 = forever */
    double cpu_limit;             /* --cpu-limit: RLIMIT_CPU seconds, 0 = none */
    uint64_t memory_limit;        /* --memory-limit: RLIMIT_AS bytes, 0 = none */
    char worker_path[PATH_MAX];   /* --worker PATH ("" = next to shapematchd) */
    int worker_threads;           /* --worker-threads: OpenMP/BLAS threads per worker, 0 = cores/workers */
    int http_threads;             /* --http-threads: MHD polling threads */
    unsigned max_connections;     /* --max-connections */
    unsigned max_connections_per_ip; /* --max-connections-per-ip */
    unsigned connection_timeout;  /* --connection-timeout: idle seconds */
    uint64_t connection_memory;   /* --connection-memory: per-connection pool */
    double shutdown_grace;        /* --shutdown-grace: wait for running jobs */
    double keepalive;             /* --keepalive: idle event streams get ": keepalive" */
    double kill_grace;            /* --kill-grace: SIGTERM -> SIGKILL delay */
    int log_level;                /* --log-level debug|info|warn|error */
    /* --cors-origin ORIGIN (repeatable; SHAPEMATCH_CORS_ORIGINS a comma
     * list): exact origins, or "*" (refused with --tokens-file) */
    char cors_origins[SMD_CORS_ORIGINS_MAX][SMD_ORIGIN_MAX];
    unsigned ncors_origins;
    char public_url[SMD_ORIGIN_MAX]; /* --public-url: the daemon's URL seen by browsers ("" = none) */
    /* --allowed-host NAME[:PORT] (repeatable; SHAPEMATCH_ALLOWED_HOSTS a
     * comma list): names the daemon is reached by (Host allow-list) */
    char allowed_hosts[SMD_ALLOWED_HOSTS_MAX][SMD_ORIGIN_MAX];
    unsigned nallowed_hosts;
    /* Several machines (server/store/pg/smd_pg.h): a PostgreSQL job store and queue
     * shared by every node; "" = the embedded spool and queue. */
    char database[SMD_DATABASE_URL_MAX]; /* --database URL (libpq conninfo or URI) */
    char database_password_file[PATH_MAX]; /* --database-password-file FILE */
    int role;                     /* --role: SMD_ROLE_ALL, _API, _WORKER */
    int max_attempts;             /* --max-attempts: runs of one job (leases lost) */
    double lease;                 /* --lease: a worker node's hold on a job */
    double db_statement_timeout;  /* --database-statement-timeout: statement_timeout */
    double db_lock_timeout;       /* --database-lock-timeout: lock_timeout */
    double db_idle_timeout;       /* --database-idle-timeout: idle_in_transaction_session_timeout */
    uint64_t max_body_memory;     /* --max-body-memory: bodies held in memory, all requests */
    uint64_t outbox_max;          /* --outbox-max: a worker node's spooled outbox, bytes */
    double body_stall_timeout;    /* --body-stall-timeout: a body without a byte this long is cut */
    unsigned max_streams_per_ip;  /* --max-streams-per-ip: streams + bodies of one address */
    unsigned submit_rate;         /* --submit-rate: submissions per window per tenant/address, 0 = none */
    double submit_window;         /* --submit-window: its window, seconds */
    unsigned submit_ipv4_prefix;  /* --submit-ipv4-prefix: IPv4 clients' limit key, bits */
    unsigned max_queued;          /* --max-queued: unfinished jobs per tenant/address, 0 = none */
    unsigned max_batch_targets;   /* --max-batch-targets: members of one batch (1..1000) */
    double header_timeout;        /* --header-timeout: request line + headers, absolute */
    uint64_t min_upload_rate;     /* --min-upload-rate: bytes/s of a body after --header-timeout */
    unsigned reserved_connections; /* --reserved-connections: kept for short requests (0 given: max/10) */
    int check_threads;            /* --check-threads: acceptance checks at once */
    double check_timeout;         /* --check-timeout: wall time of one upload's check */
} smd_config;

enum { SMD_ROLE_ALL = 0, SMD_ROLE_API = 1, SMD_ROLE_WORKER = 2 };

/* Looks up an environment variable (getenv in the daemon; a table in
 * tests).  Returns NULL when unset. */
typedef const char *(*smd_env_fn)(const char *name, void *user);

typedef enum smd_config_result {
    SMD_CONFIG_OK = 0,
    SMD_CONFIG_HELP = 1,    /* --help: print smd_config_help, exit 0 */
    SMD_CONFIG_VERSION = 2, /* --version */
    SMD_CONFIG_ERROR = 3    /* msg names the flag or variable */
} smd_config_result;

/* Fills c with the defaults, then the environment, then argv[1..]. */
smd_config_result smd_config_parse(smd_config *c, int argc, char **argv,
                                   smd_env_fn env, void *env_user, char *msg,
                                   size_t cap);

void smd_config_help(FILE *out);

/* The options whose value is a number, for tests that walk the table:
 * the i-th of them (from 0) into out, 0 past the last. */
typedef struct smd_config_number {
    const char *flag;
    enum { SMD_CONFIG_INTEGER, SMD_CONFIG_SIZE, SMD_CONFIG_DURATION } kind;
    double lo, hi;        /* the accepted range, bounds included */
    size_t width;         /* bytes of the field it is stored in */
    int is_signed;
} smd_config_number;
int smd_config_number_at(size_t i, smd_config_number *out);

/* Number of online processors (default of --workers), at least 1. */
int smd_default_workers(void);

#endif
