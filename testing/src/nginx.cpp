// The test nginx (nginx.h).
#include "sandtable/testing/nginx.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <thread>
#include <vector>

extern char** environ;

namespace sandtable::testsupport {

namespace {

std::uint16_t freeTcpPort() {
  const int s = ::socket(AF_INET, SOCK_STREAM, 0);
  if (s < 0) return 0;
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = 0;
  socklen_t len = sizeof a;
  std::uint16_t port = 0;
  if (::bind(s, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0 && ::getsockname(s, reinterpret_cast<sockaddr*>(&a), &len) == 0) {
    port = ntohs(a.sin_port);
  }
  ::close(s);
  return port;
}

bool accepts(std::uint16_t port) {
  const int s = ::socket(AF_INET, SOCK_STREAM, 0);
  if (s < 0) return false;
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(port);
  const bool ok = ::connect(s, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  ::close(s);
  return ok;
}

}  // namespace

std::unique_ptr<Nginx> Nginx::start(const std::string& root, std::uint16_t port, std::string& why) {
  auto n = std::unique_ptr<Nginx>(new Nginx());
  n->root_ = std::filesystem::absolute(root).string();
  n->port_ = port ? port : freeTcpPort();
  return n->begin(why) ? std::move(n) : nullptr;
}

std::unique_ptr<Nginx> Nginx::startTls(const std::string& root, const std::string& certFile, const std::string& keyFile,
                                       std::string& why) {
  auto n = std::unique_ptr<Nginx>(new Nginx());
  n->root_ = std::filesystem::absolute(root).string();
  n->cert_ = std::filesystem::absolute(certFile).string();
  n->key_ = std::filesystem::absolute(keyFile).string();
  n->port_ = freeTcpPort();
  return n->begin(why) ? std::move(n) : nullptr;
}

bool Nginx::begin(std::string& why) {
  std::string tmpl = (std::filesystem::temp_directory_path() / "sandtable-nginx-XXXXXX").string();
  if (!::mkdtemp(tmpl.data())) {
    why = "mkdtemp failed";
    return false;
  }
  dir_ = tmpl;
  return launch(why);
}

bool Nginx::launch(std::string& why) {
  const std::string d = dir_;
  std::filesystem::create_directories(d + "/tmp");
  {
    std::ofstream c(d + "/nginx.conf");
    c << "daemon off;\nmaster_process off;\nworker_processes 1;\npid " << d << "/nginx.pid;\n"
      << "error_log " << d << "/error.log warn;\n"
      << "events { worker_connections 256; }\n"
      << "http {\n  access_log " << d << "/access.log;\n  client_body_temp_path " << d << "/tmp;\n"
      << "  keepalive_requests 100000;\n  keepalive_timeout 60s;\n  sendfile on;\n"
      << "  types { application/octet-stream bin; }\n  default_type application/octet-stream;\n"
      << "  server {\n    listen 127.0.0.1:" << port_ << (cert_.empty() ? "" : " ssl http2") << ";\n";
    if (!cert_.empty()) c << "    ssl_certificate " << cert_ << ";\n    ssl_certificate_key " << key_ << ";\n";
    c << "    root " << root_ << ";\n    location / { }\n  }\n}\n";
  }
  std::vector<std::string> args = {"nginx", "-p", d, "-c", d + "/nginx.conf", "-e", d + "/error.log"};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&fa, STDERR_FILENO, (d + "/stderr.log").c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  // Debian puts nginx in /usr/sbin, which a user's PATH may lack.
  const char* path = std::filesystem::exists("/usr/sbin/nginx") ? "/usr/sbin/nginx" : "nginx";
  const int rc = posix_spawnp(&pid_, path, &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) {
    why = "nginx is not installed (tools/setup.sh installs nginx-light)";
    pid_ = -1;
    return false;
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (std::chrono::steady_clock::now() < deadline) {
    if (accepts(port_)) return true;
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      std::ifstream e(d + "/stderr.log");
      std::string line, all;
      while (std::getline(e, line)) all += line + " ";
      why = "nginx exited: " + all;
      return false;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  why = "nginx did not accept connections on 127.0.0.1:" + std::to_string(port_) + " within 5 s";
  stop();
  return false;
}

void Nginx::stop() {
  if (pid_ <= 0) return;
  ::kill(pid_, SIGTERM);
  int status = 0;
  ::waitpid(pid_, &status, 0);
  pid_ = -1;
}

bool Nginx::restart(std::string& why) {
  stop();
  return launch(why);
}

Nginx::~Nginx() {
  stop();
  std::error_code ec;
  std::filesystem::remove_all(dir_, ec);
}

std::string Nginx::url() const { return (cert_.empty() ? "http://" : "https://") + std::string("127.0.0.1:") + std::to_string(port_); }

std::uint64_t Nginx::requests() const {
  std::ifstream in(dir_ + "/access.log");
  std::uint64_t n = 0;
  std::string line;
  while (std::getline(in, line)) ++n;
  return n;
}

Nginx::Served Nginx::served(const std::string& path) const {
  // The combined format: ... "GET /db/grid.stg HTTP/1.1" 206 45056 "-" "-"
  std::ifstream in(dir_ + "/access.log");
  Served s;
  std::string line;
  const std::string needle = " " + path + " HTTP/";
  while (std::getline(in, line)) {
    const auto at = line.find(needle);
    if (at == std::string::npos) continue;
    const auto close = line.find('"', at);
    if (close == std::string::npos) continue;
    unsigned status = 0;
    unsigned long long bytes = 0;
    if (std::sscanf(line.c_str() + close + 1, " %u %llu", &status, &bytes) != 2) continue;
    ++s.requests;
    s.bytes += bytes;
    if (status == 206) ++s.ranges;
    if (status == 200 && bytes > 0) ++s.whole;
  }
  return s;
}

}  // namespace sandtable::testsupport
