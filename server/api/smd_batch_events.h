/* GET /v1/batches/{id}/events: a batch's progress as a stream
 * (docs/api.md, "Batches").
 *
 * The stream is the job event stream's follower (api/smd_stream.h) with a
 * source instead of a log: woken when the model job or any member
 * changes, it compares the batch document (api/smd_batches.h) with what
 * it sent last and sends
 *
 *   "target"  one member whose status, progress, iteration or message
 *             changed (its entry of the document's "targets");
 *   "batch"   the whole batch's status, progress, ETA and counts, after
 *             every change, with the event id;
 *   "status"  last: the batch document, once the model job ended and no
 *             target is queued or running (a cancel ends the model job
 *             first, then the targets), or at once when it was deleted.
 *
 * The events are states, not a log: an event id is the batch's version,
 * the number of events in the logs of the model job and its members
 * together (each grows by one with every change).  A client resuming with
 * Last-Event-ID (or ?after= in NDJSON) equal to the current version gets
 * nothing until the next change; with any other it gets the current state
 * of every target again, then follows.  A fresh stream starts with every
 * target.  Tenancy is the batch routes': a batch the requester does not
 * see is 404. */
#ifndef SMD_BATCH_EVENTS_H
#define SMD_BATCH_EVENTS_H

#include "http/smd_reply.h"

enum MHD_Result smd_route_batch_events(struct MHD_Connection *conn, smd_request *req);

#endif
