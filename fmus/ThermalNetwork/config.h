/* ThermalNetwork: model-specific configuration (the network's shape; its values are parameters). */
#ifndef THERMAL_CONFIG_H
#define THERMAL_CONFIG_H

#define TN_NODES 18
#define TN_EDGES 23
#define TN_INPUTS 4 /* t_room, q_hydraulic, q_friction, q_pole_heater */
#define TN_AUG (2 * TN_NODES + TN_INPUTS)

typedef struct {
    double phi[TN_NODES * TN_NODES];     /* T(t+h) = phi T(t) + gamma u      */
    double gamma[TN_NODES * TN_INPUTS];
    double psi[TN_NODES * TN_NODES];     /* int_t^{t+h} T dt = psi T(t) + lambda u */
    double lambda[TN_NODES * TN_INPUTS];
    double phi_h;                        /* the step these matrices were made for */
    double temp[TN_NODES];               /* node temperatures, K */
    double energy_stored0;               /* sum C_i T_i at initialization, J */
    double energy_in;                    /* J since initialization */
    double energy_lost;                  /* J since initialization */
} ModelState;

#define INTERNAL_STEP_VR VR_solver_step

#endif
