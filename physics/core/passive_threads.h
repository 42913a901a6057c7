// Programs that share a machine: idle OpenMP threads must sleep, not spin.
// With OMP_WAIT_POLICY unset, libgomp spins a waiting thread for a while
// before it sleeps; on a machine where another process holds a core that
// turned a 2.5 s compression run into 270 s. libgomp reads the variable when
// the library is loaded, before main(), so setting it in main() is too late:
// the program sets it and replaces itself with a fresh image of itself.
#pragma once

namespace cellflow {

// Call first thing in main(). If OMP_WAIT_POLICY is unset, sets it to
// "passive" and re-executes /proc/self/exe with the same arguments; returns
// (having changed nothing else) when the variable was already set, which is
// how a user who wants spinning threads asks for them (OMP_WAIT_POLICY=active),
// or when re-executing is not possible.
void ensure_passive_openmp_wait(char** argv);

}  // namespace cellflow
