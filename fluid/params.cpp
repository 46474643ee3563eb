#include "fluid/params.hpp"

#include "core/error.hpp"

namespace tetfsi::fluid {

Reconstruction parse_reconstruction(const std::string& name) {
  return k_reconstruction_names.parse(name);
}

const char* to_string(Reconstruction r) {
  return k_reconstruction_names.name(r);
}

const char* to_string(TransferScheme s) {
  return k_transfer_scheme_names.name(s);
}

const char* to_string(ScalarInterpolation s) {
  return k_scalar_interpolation_names.name(s);
}

}  // namespace tetfsi::fluid
