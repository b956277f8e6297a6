/* LD_PRELOAD shim for the SITL: getaddrinfo() for the MSP port (5761) takes 30 ms.
 *
 * The SITL calls it inside dyad_listenEx(), after dyad_newStream() has put the half-made
 * UART1 server (state CLOSED) into dyad's stream list and before it is LISTENING.  Its TCP
 * thread frees CLOSED streams every 10 ms, so with this delay the race that a loaded machine
 * loses now and then is lost every time: the port listens, and nothing ever accepts. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <netdb.h>
#include <string.h>
#include <unistd.h>
int getaddrinfo(const char *node, const char *service, const struct addrinfo *hints,
                struct addrinfo **res) {
  static int (*real)(const char *, const char *, const struct addrinfo *, struct addrinfo **);
  if (!real) real = dlsym(RTLD_NEXT, "getaddrinfo");
  if (service && strcmp(service, "5761") == 0) usleep(30000);
  return real(node, service, hints, res);
}
