// The compiled core's module: each binding file adds its part (bind/common.hpp).
#include "bind/common.hpp"

NB_MODULE(_core, m) {
    using namespace boxccd::bind;
    m.doc() = "Compiled core of bullet_boxccd: the BMS box-box time-of-impact solver.";
    bind_solver(m);   // errors, Tolerances, boxes and motions, the queries
    bind_results(m);  // Contact and Feature
    bind_paths(m);    // step paths: path rows, BoxPath, RowBoxPath
    bind_chain(m);    // link paths: Chain, ChainMotion, LinkBoxPath
    bind_world(m);    // the plugin's per-step world work: Sweeper and the tables' queries
}
