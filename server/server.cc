#include "server/server.h"

#include <algorithm>
#include <chrono>
#include <memory>
#include <string>
#include <utility>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/time/clock.h"
#include "grpcpp/ext/proto_server_reflection_plugin.h"
#include "grpcpp/generic/async_generic_service.h"
#include "grpcpp/health_check_service_interface.h"
#include "grpcpp/impl/server_builder_option.h"
#include "grpcpp/impl/server_builder_plugin.h"
#include "server/ops/observed_gallery_store.h"
#include "server/security/security.h"

namespace shapeid {
namespace {

// Server reflection is registered as a plugin of every ServerBuilder of the process; the
// health-only port must not answer it (it would list the service on a port without TLS or
// keys).
class WithoutReflection final : public grpc::ServerBuilderOption {
 public:
  void UpdateArguments(grpc::ChannelArguments* /*args*/) override {}
  void UpdatePlugins(std::vector<std::unique_ptr<grpc::ServerBuilderPlugin>>* plugins) override {
    plugins->erase(std::remove_if(plugins->begin(), plugins->end(),
                                  [](const std::unique_ptr<grpc::ServerBuilderPlugin>& plugin) {
                                    return absl::StrContains(plugin->name(), "reflection");
                                  }),
                   plugins->end());
  }
};

// What the health-only port answers for every method but grpc.health.v1's (registered by
// the server itself, which take precedence): a port needs at least one service to start.
class HealthOnly final : public grpc::CallbackGenericService {
 public:
  grpc::ServerGenericBidiReactor* CreateReactor(
      grpc::GenericCallbackServerContext* /*context*/) override {
    class Refusal final : public grpc::ServerGenericBidiReactor {
     public:
      Refusal() {
        Finish(grpc::Status(grpc::StatusCode::UNIMPLEMENTED,
                            "this port (--health_listen) answers grpc.health.v1 only; call the "
                            "server's main port"));
      }
      void OnDone() override { delete this; }
    };
    return new Refusal;
  }
};

// The address a server bound: a TCP address with the port it got (port 0 asks for any), or
// a Unix socket's as it was given.
std::string BoundAddress(const std::string& listen, int port) {
  if (absl::StartsWith(listen, "unix:") || absl::StartsWith(listen, "unix-abstract:")) {
    return listen;
  }
  return absl::StrCat(listen.substr(0, listen.rfind(':')), ":", port);
}

}  // namespace

absl::StatusOr<std::unique_ptr<ShapeIdServer>> ShapeIdServer::Start(const ServerOptions& options) {
  absl::StatusOr<std::unique_ptr<ShapeIdServer>> server = Bind(options);
  if (!server.ok()) return server.status();
  if (absl::StatusOr<LoadReport> loaded = (*server)->LoadGalleries(); !loaded.ok()) {
    return loaded.status();
  }
  return server;
}

absl::StatusOr<std::unique_ptr<ShapeIdServer>> ShapeIdServer::Bind(const ServerOptions& options) {
  // Both must be set before the builder exists.
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();

  if (absl::Status s = ValidateApproximateOptions(options.gallery_limits.approximate); !s.ok()) {
    return s;
  }
  absl::StatusOr<std::shared_ptr<const ApiKeyStore>> keys = LoadApiKeys(options.security);
  if (!keys.ok()) return keys.status();
  if (absl::Status s = CheckExposure(options.listen, options.security, !(*keys)->empty());
      !s.ok()) {
    return s;
  }
  absl::StatusOr<std::shared_ptr<grpc::ServerCredentials>> credentials =
      ListeningCredentials(options.security);
  if (!credentials.ok()) return credentials.status();
  std::unique_ptr<ShapeIdServer> server(new ShapeIdServer);
  server->logger_ = std::make_shared<Logger>(options.log);
  server->metrics_ = std::make_shared<ServerMetrics>(options.metrics);
  std::shared_ptr<GalleryStore> store;
  if (!options.store.empty()) {
    if (!absl::StartsWith(options.store, "postgres://") &&
        !absl::StartsWith(options.store, "postgresql://")) {
      return absl::InvalidArgumentError(
          "--store must be empty (galleries in --data_dir) or a PostgreSQL connection URI, "
          "postgres://[user@]host[:port]/database[?options]");
    }
    PostgresGalleryStoreOptions postgres_options;
    postgres_options.conninfo = options.store;
    absl::StatusOr<std::unique_ptr<PostgresGalleryStore>> postgres =
        PostgresGalleryStore::Open(std::move(postgres_options));
    if (!postgres.ok()) return postgres.status();
    server->postgres_store_ = *std::move(postgres);
    ReplicationFollowerOptions follower_options;
    follower_options.refresh = options.store_refresh;
    follower_options.logger = server->logger_;
    server->follower_ =
        std::make_shared<ReplicationFollower>(server->postgres_store_, std::move(follower_options));
    server->store_description_ =
        absl::StrCat("PostgreSQL ", DescribeConninfo(options.store), " (shared)");
    store = server->postgres_store_;
  } else if (!options.data_dir.empty()) {
    absl::StatusOr<std::unique_ptr<SqliteGalleryStore>> sqlite = SqliteGalleryStore::Open(
        SqliteGalleryStoreOptions{options.data_dir, options.set_aside_damaged});
    if (!sqlite.ok()) return sqlite.status();
    server->store_ = *std::move(sqlite);
    server->store_description_ = options.data_dir;
    store = server->store_;
  }
  if (store != nullptr) {
    store = std::make_shared<ObservedGalleryStore>(std::move(store), server->metrics_);
  }
  CatchUpFunction catch_up;
  if (server->follower_ != nullptr) {
    // Weak: a gallery held by a stream may outlive the server; it then has nothing to catch
    // up with.
    catch_up = [follower =
                    std::weak_ptr<ReplicationFollower>(server->follower_)](absl::string_view name) {
      const std::shared_ptr<ReplicationFollower> held = follower.lock();
      return held != nullptr ? held->CatchUp(name) : absl::OkStatus();
    };
  }
  server->registry_ =
      std::make_shared<GalleryRegistry>(options.gallery_limits, store, std::move(catch_up));
  server->service_ = std::make_unique<ShapeIdService>(
      options.service, server->registry_, *keys, CallObserver(server->metrics_, server->logger_));
  server->security_ = DescribeSecurity(options.security, **keys);
  if (options.learn) {
    GalleryLearnerOptions learner = options.learner;
    // A fit's working copy of the vectors is held in the memory budget, as the server's own
    // caller: a fit that does not fit now waits for a later try.
    learner.reserve = [budget = server->service_->shared_budget()](
                          int64_t bytes) -> absl::StatusOr<std::shared_ptr<void>> {
      absl::StatusOr<MemoryBudget::Grant> grant =
          budget->Reserve("server:learn", static_cast<size_t>(bytes), "fitting a gallery's head");
      if (!grant.ok()) return grant.status();
      return std::shared_ptr<void>(std::make_shared<MemoryBudget::Grant>(*std::move(grant)));
    };
    learner.on_fitted = [logger = server->logger_](const std::string& gallery,
                                                   const GalleryHead& head) {
      logger->Info(absl::StrFormat("gallery '%s': head fitted on %d vectors in %.1f s, %.1f %% "
                                   "on %d held-out vectors",
                                   gallery, head.fitted_rows, absl::ToDoubleSeconds(head.fit_time),
                                   100 * head.holdout_accuracy(), head.holdout_rows),
                   {{"gallery", gallery}, {"fitted_vectors", head.fitted_rows}});
    };
    server->learner_options_ = std::move(learner);
  }
  server->service_->HoldUntilLoaded();

  grpc::ServerBuilder builder;
  builder.AddListeningPort(options.listen, *credentials, &server->port_);
  builder.RegisterService(server->service_.get());
  builder.SetMaxReceiveMessageSize(options.max_message_bytes);
  // No thread-count option: gRPC 1.51's callback API runs reactions on its own executor,
  // which ResourceQuota::SetMaxThreads does not govern (docs/performance.md).
  server->server_ = builder.BuildAndStart();
  if (server->server_ == nullptr || server->port_ == 0) {
    return absl::UnavailableError(absl::StrCat(
        "cannot listen on ", options.listen, " (address in use, or not an address of this host)"));
  }
  server->address_ = BoundAddress(options.listen, server->port_);
  if (!options.health_listen.empty()) {
    // Its own grpc::Server: a port of the main one would serve every service there too. It
    // gets the default health service, whose status SetServing keeps equal to the main one's.
    grpc::ServerBuilder health_builder;
    int health_port = 0;
    health_builder.AddListeningPort(options.health_listen, grpc::InsecureServerCredentials(),
                                    &health_port);
    health_builder.SetOption(std::make_unique<WithoutReflection>());
    server->health_only_ = std::make_unique<HealthOnly>();
    health_builder.RegisterCallbackGenericService(server->health_only_.get());
    server->health_server_ = health_builder.BuildAndStart();
    if (server->health_server_ == nullptr || health_port == 0) {
      return absl::UnavailableError(absl::StrCat("cannot listen on ", options.health_listen,
                                                 " (--health_listen): address in use, or not "
                                                 "an address of this host"));
    }
    server->health_address_ = BoundAddress(options.health_listen, health_port);
  }
  if (absl::Status s = server->StartMetrics(options.metrics); !s.ok()) return s;
  server->service_->SetDescription({server->store_description_, server->metrics_address_});
  // The default health service starts out SERVING; say otherwise until the galleries are
  // loaded. (A probe in the microseconds between the two would see SERVING, but every RPC
  // is refused "loading" until LoadGalleries is done, so nothing can be served early.)
  server->SetServing(false);
  return server;
}

absl::Status ShapeIdServer::StartMetrics(const MetricsOptions& options) {
  ShapeIdService* service = service_.get();
  ReplicationFollower* follower = follower_.get();
  LiveSources live;
  live.calls_in_flight = [service] { return service->calls_in_flight(); };
  live.serving = [service] { return service->serving(); };
  live.work = [service] {
    std::vector<WorkLaneState> lanes;
    for (const WorkLane lane : {WorkLane::kCheap, WorkLane::kHeavy, WorkLane::kStore}) {
      const WorkScheduler::LaneStats stats = service->scheduler().stats(lane);
      lanes.push_back({WorkLaneName(lane), stats.workers, stats.running, stats.queued,
                       absl::ToDoubleSeconds(stats.queued_cost)});
    }
    return lanes;
  };
  live.backlog = [service] {
    const WorkScheduler::BacklogStats backlog = service->scheduler().backlog();
    return WorkBacklogState{absl::ToDoubleSeconds(backlog.total), backlog.callers};
  };
  live.learner = [this]() -> std::optional<LearnerState> {
    const GalleryLearner* learner = learner_for_metrics_.load();
    if (learner == nullptr) return std::nullopt;
    return LearnerState{learner->fits(), learner->failures(), !learner->fitting().empty()};
  };
  live.memory = [service] {
    const MemoryBudget& budget = service->budget();
    return MemoryBudgetState{budget.total_bytes(), budget.held_bytes(), budget.peak_bytes()};
  };
  if (follower != nullptr) {
    live.replication = [follower]() -> std::optional<ReplicationState> {
      return ReplicationState{follower->reachable(), follower->changes_applied(),
                              absl::Now() - follower->last_sync()};
    };
  }
  metrics_->SetSources(registry_, std::move(live));
  if (options.listen.empty()) return absl::OkStatus();
  // civetweb (inside prometheus-cpp) throws when it cannot listen.
  try {
    exposer_ = std::make_unique<prometheus::Exposer>(options.listen, /*num_threads=*/2);
  } catch (const std::exception& e) {
    return absl::UnavailableError(absl::StrCat("cannot listen on ", options.listen,
                                               " (--metrics_listen): address in use, or not an "
                                               "address of this host (",
                                               e.what(), ")"));
  }
  exposer_->RegisterCollectable(metrics_);
  const std::vector<int> ports = exposer_->GetListeningPorts();
  const size_t colon = options.listen.rfind(':');
  metrics_address_ =
      absl::StrCat(options.listen.substr(0, colon), ":", ports.empty() ? 0 : ports.front());
  return absl::OkStatus();
}

absl::StatusOr<LoadReport> ShapeIdServer::LoadGalleries() {
  LoadReport report;
  const absl::Time start = absl::Now();
  if (absl::Status status = registry_->LoadFromStore(); !status.ok()) return status;
  report.elapsed = absl::Now() - start;
  report.persistent = store_ != nullptr || postgres_store_ != nullptr;
  report.store = store_description_;
  if (store_ != nullptr) {
    report.read_only = store_->read_only();
    report.set_aside = store_->set_aside();
    report.read_only_galleries = store_->read_only_galleries();
  }
  for (const std::shared_ptr<Gallery>& gallery : registry_->All()) {
    ++report.galleries;
    report.samples += gallery->Snapshot()->num_samples();
  }
  load_report_ = report;
  if (shut_down_) return report;
  service_->StartServing();
  SetServing(true);
  if (learner_options_.has_value()) {
    learner_ = std::make_unique<GalleryLearner>(*learner_options_, registry_.get());
    learner_for_metrics_ = learner_.get();
  }
  if (follower_ != nullptr) {
    // From here on other replicas' changes are applied as they come; losing PostgreSQL for
    // longer than the refresh bound takes this replica out of service until it is back.
    follower_->Start(registry_.get(), [this](bool reachable) {
      service_->SetStoreReachable(reachable);
      SetServing(reachable);
    });
  }
  return report;
}

void ShapeIdServer::Shutdown(absl::Duration grace) {
  if (learner_ != nullptr) learner_->Stop();  // a fit in progress stops within a mini-batch
  if (shut_down_ || server_ == nullptr) return;
  // First, so that it cannot turn the service back to serving while it drains.
  if (follower_ != nullptr) follower_->Stop();
  shut_down_ = true;
  SetServing(false);
  // Drain ourselves, then shut gRPC down at once: Server::Shutdown(deadline) alone would also
  // wait for idle client connections and so always take the whole grace period.
  service_->StartDraining();
  const absl::Time deadline = absl::Now() + grace;
  while (service_->calls_in_flight() > 0 && absl::Now() < deadline) {
    absl::SleepFor(absl::Milliseconds(5));
  }
  // A moment for the refusals of calls that arrived while draining to be written (else
  // they end CANCELLED, which clients need not know to retry), then whatever is left is
  // cancelled.
  server_->Shutdown(std::chrono::system_clock::now() + std::chrono::milliseconds(100));
  server_->Wait();
  if (health_server_ != nullptr) {
    health_server_->Shutdown(std::chrono::system_clock::now());
    health_server_->Wait();
  }
  // Last: a scrape during the drain still sees it.
  exposer_.reset();
}

void ShapeIdServer::SetServing(bool serving) {
  for (grpc::Server* server : {server_.get(), health_server_.get()}) {
    if (server == nullptr) continue;
    grpc::HealthCheckServiceInterface* health = server->GetHealthCheckService();
    health->SetServingStatus(serving);  // "" and every service: readiness
    // Liveness: the process runs and answers, whatever its store; a replica that has lost
    // PostgreSQL is not ready but must not be restarted for it (it reconnects by itself).
    health->SetServingStatus(kLivenessHealthService, !shut_down_);
  }
}

ShapeIdServer::~ShapeIdServer() {
  // The follower calls into the registry and the service: stop it before either goes (also
  // when Bind failed half-way and Shutdown has nothing to do).
  if (follower_ != nullptr) follower_->Stop();
  Shutdown(absl::ZeroDuration());
  // The metrics may outlive this server (the store holds them); their sources may not.
  if (metrics_ != nullptr) metrics_->SetSources({}, {});
}

}  // namespace shapeid
