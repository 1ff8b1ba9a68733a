/* A plain C interface to the ORCA-3D library, for Python (ctypes) tests and benchmarks.
 *
 * An agent is a row of 12 doubles:
 *   px py pz  vx vy vz  preferred_vx preferred_vy preferred_vz  radius max_speed cooperative(0|1)
 * Parameters are a row of 6 doubles:
 *   max_neighbors time_step neighbor_dist time_horizon agent_radius max_speed
 * A plane is a row of 6 doubles: point xyz, normal xyz.
 * Functions return 0 on success, 2 on bad input and 1 on an internal failure; in both
 * failure cases `error` receives a sentence naming the field (truncated to error_size). */
#pragma once

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

enum { MAGNA_ORCA_AGENT_FIELDS = 12, MAGNA_ORCA_PARAM_FIELDS = 6, MAGNA_ORCA_PLANE_FIELDS = 6 };

/* One agent against `n_others` candidates; writes 3 doubles and a feasibility flag. */
int magna_orca_new_velocity(const double* agent, const double* others, size_t n_others, const double* params,
                            double* velocity, int* feasible, char* error, size_t error_size);

/* Many independent one-shot problems: problem s solves agents[s] against
 * others[offsets[s] .. offsets[s + 1]) (offsets has n_problems + 1 entries).
 * `solve_seconds` (may be NULL) receives the time spent solving, input reading excluded:
 * the benchmark's per-agent figure. */
int magna_orca_new_velocity_many(const double* agents, size_t n_problems, const double* others, const size_t* offsets,
                                 const double* params, double* velocities, int* feasible, double* solve_seconds,
                                 char* error, size_t error_size);

/* Every agent against the others (k-d tree neighbour search): one ORCA step.
 * `solve_seconds` as above. */
int magna_orca_new_velocities(const double* agents, size_t n_agents, const double* params, double* velocities,
                              int* feasible, double* solve_seconds, char* error, size_t error_size);

/* The half-spaces the selected neighbours impose on the agent, nearest first; writes
 * up to n_others rows to `planes` and their count to `n_planes`. */
int magna_orca_half_spaces(const double* agent, const double* others, size_t n_others, const double* params,
                           double* planes, size_t* n_planes, char* error, size_t error_size);

/* The velocity program alone: nearest to `preferred` within `max_speed` and the planes. */
int magna_orca_solve_velocity(const double* planes, size_t n_planes, double max_speed, const double* preferred,
                              double* velocity, int* feasible, char* error, size_t error_size);

#ifdef __cplusplus
}
#endif
