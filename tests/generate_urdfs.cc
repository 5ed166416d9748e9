// Writes the URDF documents of the simulator's built-in robots (sim::ToUrdf) into a directory:
//     generate_urdfs data/urdf
// test_sim_urdf checks that the shipped files are these.

#include <fstream>
#include <iostream>
#include <string>

#include "structgp/sim/robot.h"
#include "structgp/sim/urdf.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: generate_urdfs DIRECTORY\n";
    return 2;
  }
  namespace sim = structgp::sim;
  for (const sim::Robot& robot : {sim::TwoLinkArm(), sim::ThreeLinkArm(), sim::Puma560(), sim::Panda(),
                                   sim::Ur10()}) {
    const std::string path = std::string(argv[1]) + "/" + robot.name() + ".urdf";
    std::ofstream out(path, std::ios::binary);
    out << sim::ToUrdf(robot);
    if (!out) {
      std::cerr << "generate_urdfs: cannot write " << path << "\n";
      return 1;
    }
    std::cout << path << "\n";
  }
  return 0;
}
