// Builds against the installed structgp package: one online update and one prediction.
#include <cstdio>

#include <structgp/structgp.h>

int main() {
  structgp::WeightSpaceGP model(structgp::Vector::Ones(3), 0.01, 1);
  structgp::Vector phi(3), y(1), mean(1), latent(1), noisy(1);
  phi << 1.0, 0.5, -0.25;
  y << 2.0;
  if (model.Update(phi, y) != structgp::Status::kOk) return 1;
  if (model.PredictWithVariance(phi, mean, latent, noisy) != structgp::Status::kOk) return 1;
  std::printf("consumer: mean %.4f, latent variance %.4g\n", mean[0], latent[0]);
  return (mean[0] > 1.5 && mean[0] < 2.0) ? 0 : 1;
}
