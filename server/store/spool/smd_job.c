/* The job record's memory, references and status fields (see smd_job.h). */
#include "store/spool/smd_job.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int smd_job_state_final(sm_job_state state)
{
    return state == SM_JOB_SUCCESSFUL || state == SM_JOB_FAILED || state == SM_JOB_DISMISSED;
}

/* ------------------------------------------------------------ job memory */

smd_job *smd_job_new(const char *id)
{
    smd_job *job = calloc(1, sizeof *job);
    if (!job)
        return NULL;
    memcpy(job->id, id, SMD_ID_LEN);
    job->id[SMD_ID_LEN] = '\0';
    job->created = job->started = job->finished = job->updated = -1;
    job->log_fd = -1;
    return job;
}

void smd_job_free(smd_job *job)
{
    if (job->log_fd >= 0)
        close(job->log_fd);
    if (job->ending)
        json_decref(job->ending->log_fields);
    free(job->ending);
    free(job->event_end);
    free(job->members);
    free(job);
}

void smd_job_view(const smd_job *job, smd_job *view)
{
    *view = *job;
    view->members = NULL;
    view->nmembers = 0;
    view->events_loaded = 0;
    view->event_end = NULL;
    view->event_cap = 0;
    view->log_fd = -1;
    view->ending = NULL;
    view->hash_next = NULL;
}

int smd_job_set_members(smd_job *job, const char (*ids)[SMD_ID_LEN + 1], size_t n)
{
    char (*m)[SMD_ID_LEN + 1] = n ? malloc(n * sizeof *m) : NULL;
    if (n && !m)
        return -1;
    if (n)
        memcpy(m, ids, n * sizeof *m);
    free(job->members);
    job->members = m;
    job->nmembers = n;
    return 0;
}

void smd_job_ref(smd_job *job)
{
    job->refs++;
}

void smd_job_unref(smd_job *job)
{
    if (--job->refs == 0 && job->removed)
        smd_job_free(job);
}

void smd_job_close_log(smd_job *job)
{
    if (job->log_fd >= 0) {
        close(job->log_fd);
        job->log_fd = -1;
    }
}

int smd_job_visible(const smd_job *job, const char *tenant, int admin)
{
    return admin || strcmp(job->owner, tenant ? tenant : "") == 0;
}

static int set_time(json_t *obj, const char *key, double t)
{
    char buf[SM_RFC3339_LEN];
    if (t < 0 || sm_time_format_rfc3339(t, buf) != 0)
        return 0;
    return json_object_set_new(obj, key, json_string(buf));
}

static json_t *real_or_null(double x)
{
    return isfinite(x) ? json_real(x) : json_null();
}

json_t *smd_job_status_fields(const smd_job *job)
{
    json_t *o = json_object();
    if (!o)
        return NULL;
    json_object_set_new(o, "jobID", json_string(job->id));
    if (job->name[0])
        json_object_set_new(o, "name", json_string(job->name));
    json_object_set_new(o, "processID", json_string(job->batch_model ? "shape-model" : "match"));
    json_object_set_new(o, "type", json_string("process"));
    json_object_set_new(o, "status", json_string(sm_job_state_name(job->state)));
    if (job->state == SM_JOB_SUCCESSFUL)
        json_object_set_new(o, "converged", json_boolean(!job->not_converged));
    json_object_set_new(o, "message", json_string(job->message));
    set_time(o, "created", job->created);
    set_time(o, "started", job->started);
    set_time(o, "finished", job->finished);
    set_time(o, "updated", job->updated);
    json_object_set_new(o, "progress", json_integer(job->progress));
    /* the goals of the run, for a client's progress bar */
    json_object_set_new(o, "maxIter", json_integer(job->max_iter));
    json_object_set_new(o, "tolBoundary", json_real(job->tol_boundary));
    if (job->have_progress && job->state != SM_JOB_ACCEPTED) {
        const sm_progress *p = &job->last_progress;
        /* the figures of the progress event, by the same names */
        json_t *last = json_pack("{s:i,s:o,s:o,s:o,s:o,s:o,s:o}", "iteration", p->iteration,
                                 "J", real_or_null(p->J), "step", real_or_null(p->step),
                                 "boundary_rms", real_or_null(p->boundary_rms),
                                 "boundary_max", real_or_null(p->boundary_max),
                                 "boundary_l2", real_or_null(p->boundary_l2),
                                 "min_quality", real_or_null(p->min_quality));
        json_t *distance = sm_progress_distance_to_jansson(&p->distance);
        if (last && distance)
            json_object_set_new(last, "distance", distance);
        else
            json_decref(distance);
        if (last)
            json_object_set_new(o, "lastProgress", last);
    }
    return o;
}

uint64_t smd_job_event_offset(const smd_job *job, int64_t seq)
{
    if (seq <= 1 || job->nevents == 0)
        return 0;
    if (seq > job->nevents + 1)
        seq = job->nevents + 1;
    return job->event_end[seq - 2];
}

