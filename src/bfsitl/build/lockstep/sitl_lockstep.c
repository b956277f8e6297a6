/*
 * bfsitl lockstep for the Betaflight SITL (SIMULATOR platform only).
 *
 * Written for bfsitl and applied by `bfsitl firmware build --lockstep`, which includes this
 * file at the end of src/platform/SIMULATOR/sitl.c (so it sees that file's statics) and adds a
 * few hooks there (see bfsitl/build/lockstep/patch.py).  Outside the platform only the sensor
 * drivers' locks go (accgyro.h: one thread has nothing to lock): the scheduler, the PID loop
 * and every flight feature run as they are.
 *
 * WHY, and how:
 *
 * 1. The FC clock is a counter, never the wall clock.  micros(), millis() and the scheduler's
 *    cycle counter read `lockstepClockUs`; nothing moves it but this file.
 *
 * 2. The main loop's pause between scheduler passes (delayMicroseconds_real, the only caller
 *    is run() in main.c) is where time moves: each pass advances the clock by one quantum
 *    (`lockstepPassUs`, at most 25 us, a divisor of the gyro period and of 1 ms).  Passes
 *    land exactly on every gyro target, so GYRO/FILTER/PID run once per gyro period and the
 *    passes between them run the other tasks.  Stock 4.6.0 can lock its gyro/PID tasks out
 *    for the life of the process when the first passes after boot miss a 1 us window on the
 *    wall clock; on this grid that window is always hit.
 *    A pass between two gyro targets that ran no task is followed by a jump to the next gyro
 *    target (such a pass reads the cycle counter at most LOCKSTEP_IDLE_READS times; one that
 *    ran a task reads it five times): most of those passes have nothing to do, and each still
 *    costs a walk over every task's check.  The pass after a gyro target is never skipped (the
 *    scheduler runs no other task in the gyro's own pass), so a task that falls due in the
 *    skipped time runs at most one gyro period late, the next ones one pass apart.  The gyro targets are multiples of the gyro period: the scheduler takes
 *    its first one from the clock, which boot leaves on whole milliseconds (5. below).
 *
 * 3. The first fdm packet locks the clock: from then on FC time = packet time + a fixed
 *    offset, chosen so that the clock does not jump (the scheduler cannot recover from a jump
 *    of more than one gyro period: its catch-up always aims past the next grid point).  For
 *    each packet the passes run up to its time, then exactly one reply goes back and the main
 *    thread waits for the next packet: it polls the socket for LOCKSTEP_SPIN_US (a stepping
 *    simulator answers within that, and waking a sleeping thread costs as much again), then
 *    sleeps in select(); nothing depends on how fast the host is.  A packet whose time is not newer is answered again and not applied.
 *    The reply is the servo packet followed by the timestamp of the packet it answers (a
 *    double), so a simulator that resends can tell a late answer from the current one.
 *    The main loop waits up to LOCKSTEP_BOOT_WAIT_US of wall time for the first packet: a
 *    simulator that sends it while the SITL boots (bfsitl does) locks it at its first pass,
 *    so a run is deterministic from boot.  Without one the clock free-runs until a packet
 *    comes: it follows the wall clock (sleeping when ahead), so a SITL without a simulator
 *    boots, answers MSP and the CLI as before.
 *
 * 4. Inputs take effect at a defined FC time, so a run repeats:
 *    - RC rides in the fdm datagram (fdm_packet followed by rc_packet) and is applied with the
 *      sensors when the packet is taken, before the passes it covers.  The stock RC port stays
 *      open for other tools; bfsitl does not use it in lockstep.
 *    - TCP (MSP and the CLI, through dyad) is serviced by the main thread only, just before
 *      a packet's reply goes out (see lockstepReply).  There is no TCP thread, which also
 *      removes the stock races between it and the main thread (the listen socket set up
 *      while the thread starts dyad, and the serial TX buffer it flushes while the main
 *      thread writes it).  Over UDP it is serviced once per packet.  Through shared memory
 *      (6.) only when something can be waiting, since a service is a select() over every
 *      port's sockets and costs about as much as the rest of a packet's exchange: after a
 *      packet during whose passes the FC wrote to a serial port (its output leaves in that
 *      packet's reply, as over UDP), after a packet the simulator marks (it wrote to a port
 *      just before: tcpUntilSeq), and at least every LOCKSTEP_TCP_IDLE_US of FC time (other
 *      clients, connections, closes; the stock TCP thread serviced every 10 ms).  So the
 *      simulator's own requests are read and answered in the same packets as over UDP.
 *    - The fdm thread is gone too: the main thread reads the fdm socket itself.
 *      With no other thread left, 4.6.0's motor writes skip the update lock they tried for
 *      every motor of every pass (always free here), and the gyro and accelerometer take no
 *      lock either (patch.py takes both out).
 *
 * 5. delay()/delayMicroseconds() advance the clock during boot (rounded up to whole
 *    milliseconds, which keeps the pass grid aligned with the scheduler's first gyro target)
 *    and do nothing once the main loop runs: a pass takes no FC time, as if the FC were
 *    infinitely fast, and FC time never passes the packet's time.
 *
 * 6. The exchange: UDP as above, or, when bfsitl names a file in BFSITL_LOCKSTEP_SHM, a
 *    region of shared memory (lockstepShm_t): the simulator writes the datagram and bumps
 *    requestSeq, the FC writes its reply and sets replySeq to the request it answers, and
 *    each side wakes the other with a futex on that word (the waiter polls it first, for the
 *    spin time, then sleeps in FUTEX_WAIT).  A hand-over costs at most two futex calls instead
 *    of a sendto, a select and a recv on each side; none when both sides poll: each says in
 *    the region whether it sleeps (fcSleeping, simPolling), and only a sleeper is woken.
 *    The bytes and their meaning are those of the datagram and the reply, so nothing the
 *    firmware does depends on the exchange used.  A file that cannot be mapped ends the
 *    process with the reason: bfsitl only names one for a build that has this code, and
 *    would otherwise wait on the region forever.
 *
 * Sensor timing: packet k's sensors are seen by every pass after packet k-1's time up to
 * packet k's time, and the motor command sent back is the one computed at packet k's time.
 */

#include <fcntl.h>
#include <linux/futex.h>
#include <stddef.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <unistd.h>

#ifndef LOCKSTEP_MAX_PASS_US
#define LOCKSTEP_MAX_PASS_US 25
#endif
#ifndef LOCKSTEP_BOOT_WAIT_US
#define LOCKSTEP_BOOT_WAIT_US 1000000
#endif
#ifndef LOCKSTEP_BOOT_GRID_US
#define LOCKSTEP_BOOT_GRID_US 1000ULL
#endif
#ifndef LOCKSTEP_WAIT_POLL_US
#define LOCKSTEP_WAIT_POLL_US 20000
#endif
#ifndef LOCKSTEP_SPIN_US
#define LOCKSTEP_SPIN_US 300
#endif
#ifndef LOCKSTEP_IDLE_READS
#define LOCKSTEP_IDLE_READS 3
#endif
#ifndef LOCKSTEP_FREE_RUN_IO_US
#define LOCKSTEP_FREE_RUN_IO_US 1000ULL
#endif
#ifndef LOCKSTEP_TCP_IDLE_US
#define LOCKSTEP_TCP_IDLE_US 5000ULL
#endif

typedef struct {
    fdm_packet fdm;
    rc_packet rc;
} lockstepDatagram_t;

typedef struct {
    servo_packet servo;
    double timestamp;  // of the fdm packet answered
} lockstepReply_t;

#if !LOCKSTEP_RC_VIA_RX_UDP
// BFSITL_LOCKSTEP_RX_FRAMES=1: a receiver frame per RC trailer (see lockstepRcFrameStatus).
static bool lockstepRxFrames = false;
static bool lockstepRcFresh = false;
#endif

// The shared region of 6. above; bfsitl reads the layout from the header the FC writes.
#define LOCKSTEP_SHM_MAGIC 0x6d736662U  // "bfsm"
#define LOCKSTEP_SHM_VERSION 3U
typedef struct {
    uint32_t magic;             // written last by the FC once the region is set up
    uint32_t version;
    uint32_t requestSeq;        // the simulator: one more for each datagram it writes
    uint32_t replySeq;          // the FC: the requestSeq it has answered
    uint32_t datagramBytes;     // the simulator: how much of `datagram` it wrote
    uint32_t datagramOffset;    // the FC: where `datagram` and `reply` are
    uint32_t replyOffset;
    uint32_t regionBytes;
    uint32_t tcpUntilSeq;       // the simulator: TCP is serviced after requests up to this one
    uint32_t fcSleeping;        // the FC: 1 while it sleeps on requestSeq (wake it)
    uint32_t simPolling;        // the simulator: 1 while it polls replySeq (no need to wake it)
    lockstepDatagram_t datagram;
    lockstepReply_t reply;
} lockstepShm_t;

static uint64_t lockstepClockUs;
static uint32_t lockstepCycleSkew;
static bool lockstepLoopRunning;
static bool lockstepLocked;
static uint64_t lockstepTargetUs;
static int64_t lockstepOffsetUs;
static uint32_t lockstepPassUs = LOCKSTEP_MAX_PASS_US;
static uint32_t lockstepGyroPeriodUs = 125;
static uint64_t lockstepNextIoUs;
static uint64_t lockstepPaceOriginClockUs;
static uint64_t lockstepPaceOriginWallUs;
static uint64_t lockstepPacketsTaken;
static double lockstepLastStampS;
// Busy-poll time of each wait (LOCKSTEP_SPIN_US unless BFSITL_LOCKSTEP_SPIN_US says): a spin
// is fastest when the run has cores to itself, and steals them from its neighbours when
// several runs share the cores (bfsitl sets 0 there).
static uint32_t lockstepSpinUs = LOCKSTEP_SPIN_US;
static lockstepShm_t *lockstepShm;      // NULL: the exchange is UDP
static uint32_t lockstepShmSeen;        // the last requestSeq taken
static uint64_t lockstepTcpServicedUs;  // FC time of the last TCP service (see 4. above)
static uint32_t lockstepTxHeads[SERIAL_PORT_COUNT];  // each port's TX head at that service

static void lockstepShmOpen(const char *path)
{
    const int fd = open(path, O_RDWR | O_CLOEXEC);
    struct stat info;
    if (fd < 0 || fstat(fd, &info) != 0 ||
        ((size_t)info.st_size < sizeof(lockstepShm_t) && ftruncate(fd, sizeof(lockstepShm_t)) != 0)) {
        fprintf(stderr, "[LOCKSTEP] cannot open the shared exchange %s: %s\n", path, strerror(errno));
        exit(2);
    }
    void *region = mmap(NULL, sizeof(lockstepShm_t), PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
    close(fd);
    if (region == MAP_FAILED) {
        fprintf(stderr, "[LOCKSTEP] cannot map the shared exchange %s: %s\n", path, strerror(errno));
        exit(2);
    }
    lockstepShm = region;
    lockstepShm->version = LOCKSTEP_SHM_VERSION;
    lockstepShm->datagramOffset = offsetof(lockstepShm_t, datagram);
    lockstepShm->replyOffset = offsetof(lockstepShm_t, reply);
    lockstepShm->regionBytes = sizeof(lockstepShm_t);
    // A request written before this process mapped the region is not taken: the simulator
    // locking a booting FC writes the packet again until it is answered.
    lockstepShmSeen = __atomic_load_n(&lockstepShm->requestSeq, __ATOMIC_ACQUIRE);
    __atomic_store_n(&lockstepShm->magic, LOCKSTEP_SHM_MAGIC, __ATOMIC_RELEASE);
}

static void lockstepFutexWake(uint32_t *word)
{
    syscall(SYS_futex, word, FUTEX_WAKE, 1, NULL, NULL, 0);
}

// Nothing new to take: the request already answered, or 0 while the simulator writes one.
static bool lockstepShmIdle(uint32_t seq)
{
    return seq == lockstepShmSeen || seq == 0;
}

// The next datagram from the region if one comes within timeoutUs (the word is polled for
// the first spinUs, then FUTEX_WAIT sleeps on it); its size, or -1.  The simulator sets the
// word to 0 before it writes a datagram and to the new number after: a copy during which the
// word changed is dropped and the datagram taken afresh (a seqlock), so a half-written
// datagram (one written while a resend of the one before was being taken) is never used.
static ssize_t lockstepShmTake(lockstepDatagram_t *datagram, uint32_t timeoutUs, uint32_t spinUs)
{
    uint32_t *word = &lockstepShm->requestSeq;
    uint32_t seq = __atomic_load_n(word, __ATOMIC_ACQUIRE);
    if (lockstepShmIdle(seq) && spinUs > 0) {
        const uint64_t spinUntilUs = micros64_real() + spinUs;
        do {
            seq = __atomic_load_n(word, __ATOMIC_ACQUIRE);
        } while (lockstepShmIdle(seq) && micros64_real() < spinUntilUs);
    }
    if (lockstepShmIdle(seq) && timeoutUs > 0) {
        const struct timespec timeout = { .tv_sec = timeoutUs / 1000000,
                                          .tv_nsec = (long)(timeoutUs % 1000000) * 1000 };
        // Said before the word is read again, both sequentially consistent (as the
        // simulator's store of the word and its read of this): either the new request is
        // seen here, or this is seen there and the simulator wakes the sleeper.
        __atomic_store_n(&lockstepShm->fcSleeping, 1U, __ATOMIC_SEQ_CST);
        seq = __atomic_load_n(word, __ATOMIC_SEQ_CST);
        if (lockstepShmIdle(seq)) {
            // Returns at once if the word has moved on since it was read (no lost wake-up).
            syscall(SYS_futex, word, FUTEX_WAIT, seq, &timeout, NULL, 0);
        }
        __atomic_store_n(&lockstepShm->fcSleeping, 0U, __ATOMIC_RELAXED);
        seq = __atomic_load_n(word, __ATOMIC_ACQUIRE);
    }
    if (lockstepShmIdle(seq)) {
        return -1;
    }
    const uint32_t bytes = MIN(lockstepShm->datagramBytes, (uint32_t)sizeof(*datagram));
    memcpy(datagram, &lockstepShm->datagram, bytes);
    __atomic_thread_fence(__ATOMIC_ACQUIRE);
    if (__atomic_load_n(word, __ATOMIC_RELAXED) != seq) {
        return -1;  // rewritten while copied: the next call takes the new one
    }
    lockstepShmSeen = seq;
    return (ssize_t)bytes;
}

static void lockstepSend(const lockstepReply_t *reply)
{
    if (lockstepShm == NULL) {
        udpSend(&pwmLink, reply, sizeof(*reply));
        return;
    }
    lockstepShm->reply = *reply;
    // Sequentially consistent against the simulator's "no longer polling" and its read of
    // replySeq: a simulator still polling sees the reply, one about to sleep is woken.
    __atomic_store_n(&lockstepShm->replySeq, lockstepShmSeen, __ATOMIC_SEQ_CST);
    if (__atomic_load_n(&lockstepShm->simPolling, __ATOMIC_SEQ_CST) == 0U) {
        lockstepFutexWake(&lockstepShm->replySeq);
    }
}

static void lockstepInit(void)
{
    // The main thread owns dyad: set it up before the serial ports open their listeners.
    dyad_init();
    dyad_setTickInterval(0.2f);
    dyad_setUpdateTimeout(0.0f);
    const char *spin = getenv("BFSITL_LOCKSTEP_SPIN_US");
    if (spin != NULL && spin[0] != '\0') {
        lockstepSpinUs = (uint32_t)strtoul(spin, NULL, 10);
    }
#if !LOCKSTEP_RC_VIA_RX_UDP
    const char *rxFrames = getenv("BFSITL_LOCKSTEP_RX_FRAMES");
    lockstepRxFrames = rxFrames != NULL && rxFrames[0] == '1';
#endif
    const char *shmPath = getenv("BFSITL_LOCKSTEP_SHM");
    if (shmPath != NULL && shmPath[0] != '\0') {
        lockstepShmOpen(shmPath);
    }
    printf("[LOCKSTEP] bfsitl lockstep build: FC time follows fdm packets (RC inside them), "
           "spin %u us, exchange %s\n", (unsigned)lockstepSpinUs,
           lockstepShm != NULL ? "shared memory" : "UDP");
}

static uint64_t lockstepNowUs(void)
{
    return lockstepClockUs;
}

static uint32_t lockstepCycleCounter(void)
{
    if (!lockstepLoopRunning) {
        return (uint32_t)lockstepClockUs;  // the scheduler's first gyro target: on the grid
    }
    // The scheduler may poll the cycle counter for a gyro target a few cycles ahead; each read
    // within one pass moves it on by a cycle so such a poll ends (deterministically).  The
    // count of reads also tells whether the pass ran a task (see 2. above).
    return (uint32_t)(lockstepClockUs + lockstepCycleSkew++);
}

static void lockstepAdvanceBy(uint64_t us)
{
    if (lockstepLoopRunning) {
        return;
    }
    const uint64_t until = lockstepClockUs + us;
    lockstepClockUs = ((until + LOCKSTEP_BOOT_GRID_US - 1) / LOCKSTEP_BOOT_GRID_US) * LOCKSTEP_BOOT_GRID_US;
}

static uint32_t lockstepChoosePassUs(void)
{
    taskInfo_t gyro;
    getTaskInfo(TASK_GYRO, &gyro);
    const uint32_t periodUs = gyro.desiredPeriodUs > 0 ? (uint32_t)gyro.desiredPeriodUs : 125;
    lockstepGyroPeriodUs = periodUs;
    for (uint32_t pass = LOCKSTEP_MAX_PASS_US; pass > 1; pass--) {
        if (periodUs % pass == 0 && LOCKSTEP_BOOT_GRID_US % pass == 0) {
            return pass;
        }
    }
    return 1;
}

#if !LOCKSTEP_RC_VIA_RX_UDP
// The stock status (rxRCFrameStatus) calls every check a complete frame, so 4.6.0 measures a
// receiver at its loop rate, whatever arrives.  With BFSITL_LOCKSTEP_RX_FRAMES=1 a frame is
// complete once per RC trailer taken, as a real receiver's frames are: a log's replay gives
// the firmware its receiver's rate, which the RC smoothing and feedforward measure.
static uint8_t lockstepRcFrameStatus(rxRuntimeState_t *rxRuntimeState)
{
    UNUSED(rxRuntimeState);
    if (!lockstepRcFresh) {
        return RX_FRAME_PENDING;
    }
    lockstepRcFresh = false;
    return RX_FRAME_COMPLETE;
}
#endif

static void lockstepApplyRc(const rc_packet *rc)
{
    rcPkt = *rc;
#if LOCKSTEP_RC_VIA_RX_UDP
    rxUpdateUdpChannels(rcPkt.channels, SIMULATOR_MAX_RC_CHANNELS);
#else
    if (!rc_received) {
        rxRuntimeState.channelCount = SIMULATOR_MAX_RC_CHANNELS;
        rxRuntimeState.rcReadRawFn = readRCSITL;
        rxRuntimeState.rcFrameStatusFn = lockstepRxFrames ? lockstepRcFrameStatus : rxRCFrameStatus;
        rxRuntimeState.rxProvider = RX_PROVIDER_UDP;
    }
    lockstepRcFresh = true;
#endif
    rc_received = true;
}

// Whether the FC wrote to a serial port since the last call: a port's TX head moves with
// every byte written (all of the SITL's UARTs are TCP ports); always walks every port, so the
// heads stay current.  Only through shared memory: over UDP every packet is serviced.
static bool lockstepSerialWrote(void)
{
    bool wrote = false;
    for (unsigned i = 0; i < SERIAL_PORT_COUNT; i++) {
        const serialPortUsage_t *usage = findSerialPortUsageByIdentifier(serialPortIdentifiers[i]);
        const uint32_t head = usage != NULL && usage->serialPort != NULL ? usage->serialPort->txBufferHead : 0;
        if (head != lockstepTxHeads[i]) {
            lockstepTxHeads[i] = head;
            wrote = true;
        }
    }
    return wrote;
}

// Whether TCP is serviced after the packet just taken (see 4. above).
static bool lockstepTcpDue(void)
{
    if (lockstepShm == NULL || lockstepSerialWrote()) {
        return true;
    }
    const uint32_t until = __atomic_load_n(&lockstepShm->tcpUntilSeq, __ATOMIC_ACQUIRE);
    if ((int32_t)(until - lockstepShmSeen) >= 0) {
        return true;
    }
    return lockstepClockUs - lockstepTcpServicedUs >= LOCKSTEP_TCP_IDLE_US;
}

static void lockstepReply(double stampS)
{
    // TCP is serviced here and only here once locked, before the reply: MSP/CLI replies
    // written during the passes leave before the servo packet, and bytes that came since the
    // last service are read, to be handled in the next packet's passes.  So a request sent
    // between two packets is answered two packets later, whatever the host's timing.  The
    // RealFlight port (9001) gets nothing: the lockstep reply is bfsitl's.
    if (lockstepTcpDue()) {
        dyad_update();
        lockstepTcpServicedUs = lockstepClockUs;
    }
    const lockstepReply_t reply = { .servo = pwmPkt, .timestamp = stampS };
    lockstepSend(&reply);
}

static bool lockstepTakeDatagram(const lockstepDatagram_t *datagram, ssize_t n);

// One datagram if one comes within timeoutUs (polled for the first spinUs, then select());
// true if it was a new packet.
static bool lockstepTake(uint32_t timeoutUs, uint32_t spinUs)
{
    lockstepDatagram_t datagram;
    ssize_t n = -1;
    if (lockstepShm != NULL) {
        // -1 when nothing came: smaller than any fdm packet, so nothing is taken.
        return lockstepTakeDatagram(&datagram, lockstepShmTake(&datagram, timeoutUs, spinUs));
    }
    const uint64_t spinUntilUs = micros64_real() + spinUs;
    do {
        n = recv(stateLink.fd, &datagram, sizeof(datagram), MSG_DONTWAIT);
    } while (n < 0 && spinUs > 0 && micros64_real() < spinUntilUs);
    if (n < 0) {
        fd_set fds;
        struct timeval tv = { .tv_sec = timeoutUs / 1000000, .tv_usec = timeoutUs % 1000000 };
        FD_ZERO(&fds);
        FD_SET(stateLink.fd, &fds);
        if (select(stateLink.fd + 1, &fds, NULL, NULL, &tv) != 1) {
            return false;
        }
        n = recv(stateLink.fd, &datagram, sizeof(datagram), MSG_DONTWAIT);
    }
    return lockstepTakeDatagram(&datagram, n);
}

// One datagram taken (from either exchange): apply it, or answer a repeat; true if new.
static bool lockstepTakeDatagram(const lockstepDatagram_t *datagram, ssize_t n)
{
    if (n < (ssize_t)sizeof(fdm_packet)) {
        return false;  // not an fdm packet: ignored
    }
    const int64_t stampUs = llround(datagram->fdm.timestamp * 1e6);
    if (!lockstepLocked) {
        // No jump: the packet's time is now (see 3. above).
        lockstepOffsetUs = (int64_t)lockstepClockUs - stampUs;
        lockstepLocked = true;
        lockstepTargetUs = 0;
        printf("[LOCKSTEP] locked to the simulator at FC time %llu us (fdm time %.6f s)%s\n",
               (unsigned long long)lockstepClockUs, datagram->fdm.timestamp,
               lockstepPacketsTaken == 0 && lockstepClockUs == lockstepPaceOriginClockUs
                   ? ", at the first pass" : " after free-running");
        fflush(stdout);
    }
    const int64_t targetUs = stampUs + lockstepOffsetUs;
    if (targetUs <= (int64_t)lockstepTargetUs) {
        lockstepReply(datagram->fdm.timestamp);  // every packet gets its one answer
        return false;
    }
    lockstepLastStampS = datagram->fdm.timestamp;
    lockstepPacketsTaken++;
    if (n >= (ssize_t)sizeof(lockstepDatagram_t)) {
        lockstepApplyRc(&datagram->rc);
    }
    fdm_received = true;
    updateState(&datagram->fdm);
    lockstepTargetUs = (uint64_t)targetUs;
    return true;
}

// The end of every main-loop pass (replaces the stock 50 us sleep).
static void lockstepLoopEnd(void)
{
    const bool ranNoTask = lockstepCycleSkew <= LOCKSTEP_IDLE_READS;
    lockstepCycleSkew = 0;
    if (!lockstepLoopRunning) {
        lockstepLoopRunning = true;
        lockstepPassUs = lockstepChoosePassUs();
        lockstepPaceOriginClockUs = lockstepClockUs;
        lockstepPaceOriginWallUs = micros64_real();
        lockstepNextIoUs = lockstepClockUs;
        printf("[LOCKSTEP] main loop at FC time %llu us, a pass every %u us of FC time\n",
               (unsigned long long)lockstepClockUs, (unsigned)lockstepPassUs);
        fflush(stdout);
        if (lockstepTake(LOCKSTEP_BOOT_WAIT_US, 0)) {
            return;  // locked at the first pass: the next pass is at the packet's time
        }
    }
    if (lockstepLocked) {
        if (lockstepClockUs >= lockstepTargetUs) {
            lockstepReply(lockstepLastStampS);
            // A stepping simulator answers within microseconds: poll briefly before sleeping.
            while (!lockstepTake(LOCKSTEP_WAIT_POLL_US, lockstepSpinUs)) {
                // The simulator is silent: FC time stands still, and TCP waits for it too.
            }
        }
        uint64_t nextUs = lockstepClockUs + lockstepPassUs;
        // Not after the gyro's own pass: the scheduler runs no other task in it.
        if (ranNoTask && lockstepClockUs % lockstepGyroPeriodUs != 0 &&
            lockstepGyroPeriodUs % lockstepPassUs == 0) {
            const uint64_t gyroUs = (lockstepClockUs / lockstepGyroPeriodUs + 1) * lockstepGyroPeriodUs;
            if (gyroUs <= lockstepTargetUs) {
                nextUs = gyroUs;
            }
        }
        lockstepClockUs = nextUs;
        return;
    }
    lockstepClockUs += lockstepPassUs;
    if (lockstepClockUs < lockstepNextIoUs) {
        return;
    }
    lockstepNextIoUs = lockstepClockUs + LOCKSTEP_FREE_RUN_IO_US;
    dyad_update();
    if (lockstepTake(0, 0)) {
        return;  // the next pass, at the packet's time, sees it
    }
    // Free run: keep the FC clock at the wall clock's pace.
    const uint64_t clockElapsedUs = lockstepClockUs - lockstepPaceOriginClockUs;
    const uint64_t wallElapsedUs = micros64_real() - lockstepPaceOriginWallUs;
    if (clockElapsedUs > wallElapsedUs) {
        microsleep((uint32_t)MIN(clockElapsedUs - wallElapsedUs, 100000ULL));
    }
}
