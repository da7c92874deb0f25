// simgate/sim/bounds.h — the range of numbers a client may put into the simulation.
//
// A service that writes simulation state from a client's numbers (a speed, a destination,
// a displacement, an angle) checks each of them here first and refuses what is not a
// finite number or lies beyond its bound: the request ends FAILED (Failure::bad_arguments)
// with a message naming the parameter, its value and the bound, and nothing is changed.
// Nothing is clamped silently.
//
// Why: MuJoCo treats a NaN, an infinity or any magnitude above 1e10 (mjMAXVAL) in qpos,
// qvel or qacc as a bad state and resets the whole world in the middle of mj_step (2.2.2:
// time back to 0, without a word to simgate's components). `human move [1e300, 0]` or a
// thousand `teleport translate [1e7]` must be refused before they get there. The bounds
// are generous for any robot and far inside what the engine computes accurately (a double
// at 1e6 still resolves 1e-10 m). docs/configuration.md lists them per service.
//
// Threads: none of its own (pure functions).
#ifndef SIMGATE_SIM_BOUNDS_H_
#define SIMGATE_SIM_BOUNDS_H_

#include <string_view>

namespace simgate::sim::bounds {

// Metres: every world coordinate a client sets or targets, and every displacement it asks
// for, lies within ±position (a world 2000 km across).
inline constexpr double position = 1e6;
// Metres per second: linear speed commands (faster than any ground vehicle).
inline constexpr double linear_speed = 1e3;
// Radians per second: angular speed commands (about 160 turns a second).
inline constexpr double angular_speed = 1e3;
// Radians: angles of a rotation (about 160 turns: more is a mistake, and far beyond it the
// sine and cosine of a double lose the precision a pose needs).
inline constexpr double angle = 1e3;
// The control of an actuator without a ctrlrange (ctrllimited false), in the actuator's own
// unit (N or N·m through its gear for a motor, m or rad for a position servo): within
// ±control. An actuator with a ctrlrange takes exactly that range.
inline constexpr double control = 1e6;

// Refuses `value` unless it is finite and within ±bound:
// "x = 1e+300 is out of bounds: expected a finite number within ±1e+06 m".
void require_within(std::string_view parameter, double value, double bound, std::string_view unit);

// Refuses `value` unless it is finite and within [low, high]:
// "speed = 5000 is out of bounds: expected a finite number from 0 to 1000 m/s".
void require_between(std::string_view parameter, double value, double low, double high,
                     std::string_view unit);

// Refuses a move, asked for with `parameter` = `value`, that would take `object` ("body
// 'robot'") to a `coordinate` on `axis` ("x") beyond ±position:
// "x = 900000 would take body 'robot' to x = 1.9e+06, beyond the world bound ±1e+06 m".
void require_inside_world(std::string_view parameter, double value, std::string_view object,
                          std::string_view axis, double coordinate);

}  // namespace simgate::sim::bounds

#endif  // SIMGATE_SIM_BOUNDS_H_
