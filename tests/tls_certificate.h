#pragma once
// Certificates for the TLS tests, made with the openssl command line (deploy/install-deps.sh).

#include <cstdlib>
#include <filesystem>
#include <string>

namespace forestmap::test {

// A self-signed certificate DIR/NAME.crt with its key DIR/NAME.key, valid one day: `subject`
// e.g. "/CN=drone-7", `extension` an -addext value (e.g. "subjectAltName=IP:127.0.0.1").
// Returns "" when made, else the command that failed.
inline std::string MakeSelfSignedCertificate(const std::filesystem::path& dir,
                                             const std::string& name, const std::string& subject,
                                             const std::string& extension) {
  const std::string command = "openssl req -x509 -newkey rsa:2048 -nodes -days 1 -subj '" +
                              subject + "' -addext '" + extension + "' -keyout '" +
                              (dir / (name + ".key")).string() + "' -out '" +
                              (dir / (name + ".crt")).string() + "' 2>/dev/null";
  return std::system(command.c_str()) == 0 ? "" : command;
}

}  // namespace forestmap::test
