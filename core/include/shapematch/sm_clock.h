/* The one clock of the tree for durations: seconds on CLOCK_MONOTONIC,
 * which a change of the wall clock (NTP, an administrator) does not move.
 * Only differences mean anything.  Wall-clock times for documents and
 * logs are proto's sm_time_now. */
#ifndef SM_CLOCK_H
#define SM_CLOCK_H

double sm_clock_seconds(void);

#endif
