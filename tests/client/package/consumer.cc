// A drone program's first lines against the installed client library: a client of a forestmapd
// (here an address where none listens), and a detected trunk converted to its API message.

#include <iostream>

#include "client/lib/forestmap_client.h"
#include "client/lib/proto_convert.h"

int main() {
  forestmap::client::ClientOptions options;
  options.connect_timeout = 0.5;  // s
  forestmap::client::ForestMapClient client("127.0.0.1:1", options);

  forestmap::algorithms::DetectedTree tree;
  tree.position = Eigen::Vector3d(1.5, -2.25, 0.5);
  tree.dbh = 0.25;
  const forestmap::v1::DetectedTree message = forestmap::client::ToProto(tree);
  std::cout << "tree " << message.position().x() << " " << message.position().y() << " "
            << message.dbh() << "\n";
  try {
    client.ListMaps();
    std::cout << "ListMaps answered\n";
  } catch (const forestmap::client::RpcError& error) {
    std::cout << "ListMaps: " << error.what() << "\n";
  }
}
