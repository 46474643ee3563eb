#pragma once
/// @file process_env.hpp
/// Process-wide settings the `tetfsi` executable applies before doing any work.

namespace tetfsi::app {

/// Cap OpenMP at one thread unless the user set OMP_THREAD_LIMIT.
///
/// Debian 12's CHOLMOD (SuiteSparse 5.12) opens OpenMP regions with a compiled-in
/// num_threads(4) (CHOLMOD_OMP_NUM_THREADS) inside its supernodal factorization, while
/// OpenBLAS runs its own threads underneath. On this 2-core machine the two pools fight:
/// `perf` showed half of a CHOLMOD-bound run in the kernel (sched_yield, futex), and the
/// csm1 scene took 13–22 s with 11–13 s of system time. With OMP_THREAD_LIMIT=1 it took
/// 6–15 s with 1–3 s of system time (same runs, interleaved); the Poisson benchmark's
/// CHOLMOD and AMG figures did not change. libgomp reads OMP_THREAD_LIMIT only when it is
/// loaded, so this sets it and re-executes the program once (/proc/self/exe, same argv);
/// if that fails the program simply continues with the default.
/// It also sets OPENBLAS_NUM_THREADS=1 unless the user set it: PETSc's vector operations call
/// BLAS, and OpenBLAS's idle threads then spin in sched_yield — measured on smoke_jet (6
/// steps): 1.33 s of system time with the default, 0.14 s with one thread, same wall time.
void cap_openmp_threads(char** argv);

}  // namespace tetfsi::app
