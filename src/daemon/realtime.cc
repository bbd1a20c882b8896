#include "clutterseg/daemon/realtime.h"

#include <pthread.h>
#include <sched.h>

#include <cerrno>
#include <cstring>

#include "clutterseg/core/param_check.h"

namespace clutterseg::daemon {

void RealtimeParams::ValidateOrThrow() const {
  // 99 is left to the kernel's own threads (watchdogs, migration); the capture path takes
  // priority + 1.
  core::ParamCheck("processing").InRange("realtime_priority", priority, 0, 98, "(0 = off)");
}

bool SetThreadRealtime(int priority, std::string* problem) {
  sched_param param{};
  param.sched_priority = priority;
  const int policy = priority > 0 ? SCHED_FIFO : SCHED_OTHER;
  const int rc = pthread_setschedparam(pthread_self(), policy, &param);
  if (rc == 0) return true;
  *problem = std::string("cannot enter SCHED_FIFO at priority ") + std::to_string(priority) + ": " +
             std::strerror(rc);
  if (rc == EPERM) {
    *problem += " (needs CAP_SYS_NICE or RLIMIT_RTPRIO >= " + std::to_string(priority) +
                "; systemd: LimitRTPRIO=" + std::to_string(priority) +
                " and no RestrictRealtime=yes)";
  }
  return false;
}

bool ThreadIsRealtime() {
  int policy = SCHED_OTHER;
  sched_param param{};
  if (pthread_getschedparam(pthread_self(), &policy, &param) != 0) return false;
  return policy == SCHED_FIFO || policy == SCHED_RR;
}

ScopedNormalClass::ScopedNormalClass() {
  sched_param param{};
  if (pthread_getschedparam(pthread_self(), &policy_, &param) != 0) return;
  if (policy_ != SCHED_FIFO && policy_ != SCHED_RR) return;
  priority_ = param.sched_priority;
  sched_param normal{};
  restore_ = pthread_setschedparam(pthread_self(), SCHED_OTHER, &normal) == 0;
}

ScopedNormalClass::~ScopedNormalClass() {
  if (!restore_) return;
  sched_param param{};
  param.sched_priority = priority_;
  pthread_setschedparam(pthread_self(), policy_, &param);  // the priority it had: permitted
}

}  // namespace clutterseg::daemon
