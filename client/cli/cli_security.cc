// The global security flags of `forestmap`: TLS to the server and the bearer token.

#include "client/cli/cli_context.h"

namespace forestmap::client {

void AddSecurityOptions(CLI::App& app, CliContext& context) {
  ClientOptions& options = context.client;
  app.add_flag("--tls", options.tls,
               "connect with TLS, trusting the system's root certificates (see --tls-ca)");
  app.add_option("--tls-ca", options.tls_ca,
                 "PEM file of the CA that signed forestmapd's certificate; implies --tls "
                 "(environment FORESTMAP_TLS_CA)")
      ->envname("FORESTMAP_TLS_CA")
      ->check(CLI::ExistingFile);
  app.add_option("--tls-cert", options.tls_cert,
                 "PEM client certificate, for a server started with --tls-client-ca")
      ->check(CLI::ExistingFile);
  app.add_option("--tls-key", options.tls_key, "PEM key of --tls-cert")->check(CLI::ExistingFile);
  app.add_option("--token", options.token,
                 "access token (forestmapd token create); the environment variable "
                 "FORESTMAP_TOKEN is read when this is not given")
      ->envname("FORESTMAP_TOKEN");
}

}  // namespace forestmap::client
