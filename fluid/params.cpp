#include "fluid/params.hpp"

#include "core/error.hpp"

namespace tetfsi::fluid {

Reconstruction parse_reconstruction(const std::string& name) {
  if (name == "vertex_ls") return Reconstruction::VertexLeastSquares;
  if (name == "whitney") return Reconstruction::Whitney;
  throw InputError(
      fmt::format("unknown velocity reconstruction '{}': use vertex_ls or whitney", name));
}

const char* to_string(Reconstruction r) {
  return r == Reconstruction::Whitney ? "whitney" : "vertex_ls";
}

}  // namespace tetfsi::fluid
