#include "drivers/turntable.h"

namespace sherd::drivers {

const char* to_string(TurntableState state) {
  switch (state) {
    case TurntableState::Idle: return "idle";
    case TurntableState::Homing: return "homing";
    case TurntableState::Moving: return "moving";
    case TurntableState::Fault: return "fault";
    case TurntableState::Disconnected: return "disconnected";
  }
  return "unknown";
}

}  // namespace sherd::drivers
