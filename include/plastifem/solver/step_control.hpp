#pragma once
// Step control: a time step as a transaction, with automatic cutting.
//
// advance() makes one step of dt from the committed state: an attempt writes a trial state
// and, if it succeeds, the two are swapped. A step
// whose attempt fails (SolverError) is redone as two half steps, recursively, up to max_cuts
// times (2^max_cuts sub-steps): a huge time step becomes a sequence of smaller ones, as load
// stepping does in statics; the sub-steps advance a working copy, committed by a swap when the
// last one succeeded. Whatever is thrown, by the solver or by a user's load curve, prescribed
// path or policy, and at whatever sub-step, the committed state has not been touched.
#include <plastifem/core/log.hpp>
#include <plastifem/solver/newmark.hpp>
#include <plastifem/solver/settings.hpp>

#include <cmath>
#include <cstdint>
#include <string>

namespace plastifem {

/// Refuses a time step dt from time t that is not finite and positive, that t's round-off
/// would change (clock_represents), or whose Newmark coefficient 1 / (beta dt^2) overflows.
inline void check_time_step(Scalar dt, Scalar t, const NewmarkSettings& nm) {
  if (!(dt > 0) || !std::isfinite(dt)) fail<InvalidArgument>("time step must be finite and > 0, got dt = {}", dt);
  if (!clock_represents(t, dt))
    fail<InvalidArgument>("time step dt = {} is lost in the round-off of t = {}: t + dt is {} after t (a later start "
                          "time, or a larger step, keeps the clock exact)",
                          dt, t, (t + dt) - t);
  if (const Scalar c0 = Newmark{nm.beta, nm.gamma, dt}.c0(); !std::isfinite(c0))
    fail<InvalidArgument>("time step dt = {} is too small: the Newmark coefficient 1 / (beta dt^2) = {} overflows", dt,
                          c0);
}

/// Tells the user about a step whose prescribed paths jumped (StepReport::path_jumps).
inline void note_path_jumps(const StepReport& r, Scalar t) {
  if (r.path_jumps > 0)
    note(fmt::format("t = {}: the prescribed path (or given velocity) of {} constrained node(s) jumps at the end of "
                     "a step; they jump with it and move on at the path's velocity after the jump "
                     "(StepReport::path_jumps)",
                     t, r.path_jumps));
}

/// One (sub-)step of dt from work, cut in halves on failure while depth < max_cuts.
template <class StateT, class Attempt>
void substep(StateT& work, StateT& trial, Scalar dt, int depth, int max_cuts, StepReport& total, Attempt& attempt) {
  StepReport r;
  try {
    r = attempt(work, trial, dt);
  } catch (const SolverError&) {
    if (depth >= max_cuts) throw;
    substep(work, trial, dt / 2, depth + 1, max_cuts, total, attempt);
    substep(work, trial, dt / 2, depth + 1, max_cuts, total, attempt);
    return;
  }
  work.swap(trial);
  total.add_substep(r);
}


/// current -> current advanced by dt. `attempt(from, to, dt)` makes one step from `from`
/// into `to` and throws SolverError on failure (leaving `from` untouched). The first attempt
/// reads `current` directly; only a step that must be cut copies it into `work`, advances that
/// through the sub-steps, and commits it. `current` changes only by the final swap.
template <class StateT, class Attempt>
StepReport advance(StateT& current, StateT& work, StateT& trial, Scalar dt, int max_cuts, Attempt&& attempt) {
  StepReport r;
  try {
    r = attempt(current, trial, dt);
  } catch (const SolverError& first_failure) {
    if (max_cuts < 1) throw;
    work.assign(current);
    const Scalar t_end = current.t + dt;
    StepReport total;
    total.substeps = 0;
    try {
      substep(work, trial, dt / 2, 1, max_cuts, total, attempt);
      substep(work, trial, dt / 2, 1, max_cuts, total, attempt);
    } catch (const SolverError& e) {
      // The last failure is always one of the smallest sub-steps, dt / 2^max_cuts.
      fail<SolverError>("{} (also with the step cut into up to {} sub-steps of dt = {:.6g}: {})", first_failure.what(),
                        std::uint64_t{1} << max_cuts, std::ldexp(dt, -max_cuts), e.what());
    }
    work.t = t_end;  // exactly, whatever the sub-steps' round-off
    current.swap(work);
    return total;
  }
  current.swap(trial);
  return r;
}

}  // namespace plastifem
