// A user's program against the installed package: fit pol+fri to a robot log by evidence,
// print the summary, diagnose the model on the log and save it.
#include <cstdio>
#include <exception>

#include <structgp/structgp.h>

int main(int argc, char** argv) try {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s LOG.csv MODEL.json\n", argv[0]);
    return 2;
  }
  const structgp::RobotData log = structgp::ReadRobotCsv(argv[1]);
  const structgp::FitOptions options;  // type-II maximum likelihood
  const structgp::FittedModel fit =
      structgp::FitModel(structgp::ParseModelSpec("pol+fri"), log.X, log.Y, log.t, options);
  std::printf("%s\n%s", fit.summary.BriefReport().c_str(),
              structgp::FitReport(fit.model, fit.summary).c_str());
  if (!fit.summary.IsUsable()) return 1;
  const structgp::Diagnosis d = structgp::Diagnose(
      fit.model, structgp::ModelInputs(fit.model, log.X, log.t), log.Y, log.t);
  if (d.status != structgp::DiagnosisStatus::kOk) return 1;
  for (const auto& s : d.suggestions) std::printf("missing: %s\n", s.spec.c_str());
  structgp::SaveModel(argv[2], fit.model);
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "structgp_consumer: %s\n", e.what());
  return 2;
}
