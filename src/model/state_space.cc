#include "stagefit/model/state_space.h"

#include <Eigen/Cholesky>

#include <sstream>

#include "stagefit/common/error.h"
#include "stagefit/model/modes.h"

namespace stagefit::model {

StateSpace CalcStateSpace(const SecondOrderSystem& sys) {
  const int n = sys.num_dofs();
  StateSpace ss;
  Eigen::LLT<Eigen::MatrixXd> Mllt(sys.M);
  if (Mllt.info() != Eigen::Success) throw NumericalError("the mass matrix is not positive definite");
  Eigen::MatrixXd C = sys.C;
  if (!sys.K_loss.isZero(0.0)) {
    NormalModes nm = CalcNormalModes(sys.M, sys.K);
    Eigen::VectorXd c(n);
    for (int r = 0; r < n; ++r) {
      const double w = nm.omega_rad_s(r);
      c(r) = w > 0 ? nm.shapes.col(r).dot(sys.K_loss * nm.shapes.col(r)) / w : 0.0;
    }
    Eigen::MatrixXd MPhi = sys.M * nm.shapes;
    C += MPhi * c.asDiagonal() * MPhi.transpose();
    ss.notes.push_back("hysteretic loss factors replaced by modal equivalent viscous damping (exact at each resonance)");
  }
  if (sys.delay_s != 0.0) {
    std::ostringstream out;
    out << "acquisition delay of " << sys.delay_s << " s is not part of the state space; apply it to the outputs";
    ss.notes.push_back(out.str());
  }
  const Eigen::MatrixXd MinvK = Mllt.solve(sys.K);
  const Eigen::MatrixXd MinvC = Mllt.solve(C);
  const Eigen::MatrixXd G = Mllt.solve(sys.B2);
  ss.A = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  ss.A.topRightCorner(n, n).setIdentity();
  ss.A.bottomLeftCorner(n, n) = -MinvK;
  ss.A.bottomRightCorner(n, n) = -MinvC;
  const int ni = sys.num_inputs();
  ss.B = Eigen::MatrixXd::Zero(2 * n, ni);
  ss.B.topRows(n) = -MinvC * G;
  ss.B.bottomRows(n) = Mllt.solve(sys.B0 - sys.K * G + C * MinvC * G);
  ss.C = Eigen::MatrixXd::Zero(sys.num_outputs(), 2 * n);
  ss.C.leftCols(n) = sys.Cq;
  ss.D = sys.Cq * G + sys.D0;
  for (const auto& d : sys.dof_names) ss.state_names.push_back(d);
  for (const auto& d : sys.dof_names) ss.state_names.push_back(d + "_dot");
  ss.input_names = sys.input_names;
  ss.output_names = sys.output_names;
  return ss;
}

}  // namespace stagefit::model
