// A remote file as a RangeSource (remote_range.h).
#include "sandtable/http/remote_range.h"

namespace sandtable::http {

Result<std::shared_ptr<const RemoteRange>> RemoteRange::open(std::shared_ptr<const Client> client, const std::string& url) {
  auto f = client->open(url);
  if (!f) return f.problems();
  return std::shared_ptr<const RemoteRange>(new RemoteRange(std::move(client), std::move(f.value())));
}

}  // namespace sandtable::http
