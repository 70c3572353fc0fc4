/* HydraulicLoader: model-specific configuration (the servo's discretisation and its states). */
#ifndef HYDRAULIC_LOADER_CONFIG_H
#define HYDRAULIC_LOADER_CONFIG_H

#define HL_TABLE 8 /* points of the tabulated load profile */

typedef struct {
    /* exact zero-order-hold discretisation of the servo for the step it was made for:
     * [F; w](t+h) = phi [F; w](t) + gamma u(t), row-major 2x2 and 2x1 */
    double phi[4];
    double gamma[2];
    double step_h;
    /* servo states, without the pump ripple: the actual load F (N) and its rate scaled by the
     * natural angular frequency, w = (dF/dt) / omega_n (N), so both states have the same unit
     * and the discretised matrix is balanced */
    double load;
    double rate_scaled;
} ModelState;

#define INTERNAL_STEP_VR VR_solver_step

#endif
