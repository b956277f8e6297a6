/* LD_PRELOAD shim for the SITL: the main loop's first sleep lasts STALL_US (environment,
 * default 1000) instead of 50 us.
 *
 * The SITL's main loop is scheduler(); delayMicroseconds_real(50), the only 50 us sleep of
 * its main thread.  Stretching the first one stands in for a main thread preempted right
 * after tasksInit() on a busy machine: the scheduler's first gyro window (125..250 us of the
 * firmware's clock after schedulerInit) passes with no scheduler pass in it, which locks the
 * gyro/PID tasks out for the life of the process (sitl/process.py _check_pid_loop). */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <stdlib.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>
int nanosleep(const struct timespec *req, struct timespec *rem) {
  static int (*real)(const struct timespec *, struct timespec *);
  static int stalled;
  if (!real) real = dlsym(RTLD_NEXT, "nanosleep");
  if (!stalled && req && req->tv_sec == 0 && req->tv_nsec == 50000 &&
      syscall(SYS_gettid) == getpid()) {
    stalled = 1;
    const char *env = getenv("STALL_US");
    long stall_us = env ? atol(env) : 1000;
    struct timespec stall = {stall_us / 1000000, (stall_us % 1000000) * 1000};
    return real(&stall, NULL);
  }
  return real(req, rem);
}
