// TOML job files through load_job_file(), then every check `nmbake bake
// job.toml` makes before the first bake (validate_options,
// check_bake_inputs), as the CLI runs them.
#include "fuzz_util.hpp"
#include "nmbake/job.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const nmbake::fuzz::InputFile file(data, size, "input.toml");
  std::vector<nmbake::BakeJob> jobs;
  if (!nmbake::load_job_file(file.path(), jobs).is_ok()) return 0;
  for (const nmbake::BakeJob& job : jobs) {
    if (nmbake::validate_options(job.options).is_ok()) (void)nmbake::check_bake_inputs(job.options);
  }
  return 0;
}
