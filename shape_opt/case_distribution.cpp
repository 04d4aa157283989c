#include "shape_opt/case_distribution.hpp"

#include "adjoint/adjoint.hpp"
#include "forward/common/error.hpp"
#include "forward/common/timer.hpp"
#include "objectives/objective.hpp"
#include "shape_opt/byte_buffer.hpp"
#include "shape_opt/distribution.hpp"

#include <algorithm>
#include <stdexcept>

namespace diffipc {

namespace {

    // FAILED: COLLECTIVE mode, rank 0 could not make the request (its error follows).
    enum Command : char { LOAD = 'L', EVALUATE = 'E', STOP = 'S', FAILED = 'X' };
    // How a case (or a collective evaluation) ended: its share, or the kind of error it threw.
    enum Outcome : uint8_t {
        SHARE = 0,
        INPUT = 1,
        OBJECTIVE_DOMAIN = 2,
        ADJOINT = 3,
        OTHER = 4, ///< std::runtime_error with the message
        INVALID_ARGUMENT = 5,
        OUT_OF_RANGE = 6,
        LOGIC = 7,
        NO_MEMORY = 8,
        LAST = NO_MEMORY
    };
    // The problems a serving rank holds: the two evaluated last (a remesh evaluates the old and the new).
    constexpr size_t held_problems = 2;

    struct Failure {
        Outcome kind = OTHER;
        std::string field, message;
    };

    // The error in flight, as its kind and text (call inside a catch block).
    Failure current_failure()
    {
        try {
            throw;
        } catch (const ObjectiveDomainError& e) {
            return { OBJECTIVE_DOMAIN, e.field(), e.message() };
        } catch (const InputError& e) {
            return { INPUT, e.field(), e.message() };
        } catch (const AdjointError& e) {
            return { ADJOINT, "", e.what() };
        } catch (const std::invalid_argument& e) {
            return { INVALID_ARGUMENT, "", e.what() };
        } catch (const std::out_of_range& e) {
            return { OUT_OF_RANGE, "", e.what() };
        } catch (const std::logic_error& e) {
            return { LOGIC, "", e.what() };
        } catch (const std::bad_alloc& e) {
            return { NO_MEMORY, "", e.what() };
        } catch (const std::exception& e) {
            return { OTHER, "", e.what() };
        } catch (...) {
            return { OTHER, "", "an exception of unknown type" };
        }
    }

    // Throws the error current_failure() described, with its type and message (an InputError's message longer
    // than error.hpp's clip is clipped once more: its "(N more characters)" can differ from the serial run's).
    [[noreturn]] void rethrow(const Failure& f)
    {
        switch (f.kind) {
        case INPUT:
            throw InputError(f.field, f.message);
        case OBJECTIVE_DOMAIN:
            throw ObjectiveDomainError(f.message);
        case ADJOINT:
            throw AdjointError(f.message);
        case INVALID_ARGUMENT:
            throw std::invalid_argument(f.message);
        case OUT_OF_RANGE:
            throw std::out_of_range(f.message);
        case LOGIC:
            throw std::logic_error(f.message);
        case NO_MEMORY:
            throw std::bad_alloc();
        default:
            throw std::runtime_error(f.message);
        }
    }

    void put_failure(ByteWriter& w, const Failure& f)
    {
        w.put(uint8_t(f.kind));
        w.put_string(f.field);
        w.put_string(f.message);
    }

    Failure get_failure(ByteReader& r, uint8_t kind)
    {
        if (kind < INPUT || kind > LAST)
            throw std::invalid_argument(std::string(r.context) + ": outcome " + std::to_string(kind) + " unknown");
        Failure f;
        f.kind = Outcome(kind);
        f.field = r.string("field");
        f.message = r.string("message");
        return f;
    }

    struct Request {
        uint64_t problem = 0;
        bool gradient = false, constraints = false;
        uint64_t cases = 0;
        VectorXd p;
        std::vector<int> owner;
    };

    Request read_request(const std::string& bytes)
    {
        ByteReader r { bytes, "evaluation request" };
        if (r.get<char>("command") != EVALUATE)
            throw std::invalid_argument("evaluation request: not an EVALUATE message");
        Request q;
        q.problem = r.get<uint64_t>("problem");
        q.gradient = r.get<uint8_t>("gradient") != 0;
        q.constraints = r.get<uint8_t>("constraints") != 0;
        q.cases = r.get<uint64_t>("cases");
        q.p.resize(Index(r.count("p", sizeof(double))));
        r.doubles(q.p.data(), uint64_t(q.p.size()), "p");
        const uint64_t owners = r.count("owner", sizeof(int));
        for (uint64_t c = 0; c < owners; ++c)
            q.owner.push_back(r.get<int>("owner"));
        r.finish();
        if (q.owner.size() != q.cases)
            throw std::invalid_argument("evaluation request: " + std::to_string(q.owner.size()) + " owners for "
                + std::to_string(q.cases) + " load cases");
        return q;
    }

    std::string describe_assignment(const std::vector<int>& owner, int size)
    {
        std::string text;
        for (int r = 1; r < size; ++r) {
            std::string cases;
            int count = 0;
            for (size_t c = 0; c < owner.size(); ++c)
                if (owner[c] == r)
                    cases += (count++ ? ", " : " ") + std::to_string(c);
            if (count == 0)
                continue;
            text += (text.empty() ? "" : "; ") + std::string("rank ") + std::to_string(r)
                + (count == 1 ? ": load case" : ": load cases") + cases;
        }
        return text;
    }

} // namespace

CaseDistribution::CaseDistribution(std::shared_ptr<Communicator> communicator, Mode mode)
    : m_comm(std::move(communicator))
    , m_mode(mode)
{
    if (!m_comm)
        throw std::invalid_argument("CaseDistribution: no communicator");
    m_rank = m_comm->rank();
    m_size = m_comm->size();
    m_times.compute.assign(size_t(m_size), 0.0);
    m_times.loading.assign(size_t(m_size), 0.0);
    m_times.cases.assign(size_t(m_size), 0);
}

CaseDistribution::~CaseDistribution()
{
    try {
        stop();
    } catch (...) {
        // Nothing to do: the job is ending anyway.
    }
}

void CaseDistribution::stop()
{
    if (m_mode != Mode::DRIVER || m_rank != 0 || m_stopped || m_size == 1) {
        m_stopped = true;
        return;
    }
    m_stopped = true;
    std::string message(1, STOP);
    m_comm->broadcast(message);
}

void CaseDistribution::load_on_servers(const ReducedFunctional& J)
{
    if (m_size == 1)
        return;
    // The serving ranks hold the two problems evaluated last (least recently evaluated dropped), as this list.
    const auto held = std::find(m_loaded.begin(), m_loaded.end(), J.id());
    if (held != m_loaded.end()) {
        m_loaded.erase(held);
        m_loaded.push_back(J.id());
        return;
    }
    ByteWriter w;
    w.put(char(LOAD));
    w.put(J.id());
    w.put_string(J.document().dump());
    w.put_string(J.base_directory());
    w.put_string(J.source());
    w.put_string(J.device_override());
    m_comm->broadcast(w.bytes);
    m_loaded.push_back(J.id());
    while (m_loaded.size() > held_problems)
        m_loaded.pop_front();
}

std::string CaseDistribution::request(const ReducedFunctional& J, const VectorXd& p, bool gradient, bool constraints)
{
    if (J.id() != m_cost_problem) {
        m_cost_problem = J.id();
        m_costs.clear();
    }
    m_assignment_costs = m_costs;
    m_last_owner = assign_cases(J.load_cases(), m_costs, m_size);
    ByteWriter w;
    w.put(char(EVALUATE));
    w.put(J.id());
    w.put(uint8_t(gradient));
    w.put(uint8_t(constraints));
    w.put(uint64_t(J.load_cases()));
    w.put_doubles(p.data(), size_t(p.size()));
    w.put(uint64_t(m_last_owner.size()));
    for (const int o : m_last_owner)
        w.put(o);
    return w.bytes;
}

std::string CaseDistribution::evaluate_mine(
    const ReducedFunctional* J, const std::string& request_bytes, const std::string& load_error)
{
    const Request q = read_request(request_bytes);
    // Every case of this rank: its share, or its error.
    std::string mismatch = load_error;
    if (mismatch.empty() && !J)
        mismatch = "rank " + std::to_string(m_rank) + " does not hold the problem";
    if (mismatch.empty() && (J->load_cases() != q.cases || J->size() != q.p.size()))
        mismatch = "rank " + std::to_string(m_rank) + "'s problem has " + std::to_string(J->load_cases())
            + " load cases and " + std::to_string(J->size()) + " parameters, rank 0's " + std::to_string(q.cases)
            + " and " + std::to_string(q.p.size());
    ByteWriter records;
    uint64_t count = 0;
    double compute = 0;
    for (size_t c = 0; c < q.owner.size(); ++c) {
        if (q.owner[c] != m_rank)
            continue;
        ++count;
        const Timer timer;
        ByteWriter outcome;
        if (!mismatch.empty())
            put_failure(outcome, { OTHER, "", mismatch });
        else
            try {
                const std::string share = pack_evaluation(J->evaluate_case(c, q.p, q.gradient, q.constraints));
                outcome.put(uint8_t(SHARE));
                outcome.put_string(share);
            } catch (...) {
                put_failure(outcome, current_failure());
            }
        const double seconds = timer.seconds();
        compute += seconds;
        records.put(uint64_t(c));
        records.put(seconds);
        records.bytes += outcome.bytes;
    }
    ByteWriter reply;
    reply.put(compute);
    reply.put(m_unreported_loading);
    m_unreported_loading = 0;
    reply.put(count);
    reply.bytes += records.bytes;
    return reply.bytes;
}

Evaluation CaseDistribution::combine(
    const ReducedFunctional& J, const std::vector<std::string>& replies, bool gradient, bool constraints)
{
    const size_t cases = J.load_cases();
    std::vector<std::string> shares(cases);
    std::vector<bool> seen(cases, false);
    std::vector<double> seconds(cases, 0.0);
    size_t first_failed = cases;
    Failure failure;
    for (size_t r = 0; r < replies.size(); ++r) {
        ByteReader reader { replies[r], "evaluation reply" };
        const double compute = reader.get<double>("compute");
        const double loading = reader.get<double>("loading");
        const uint64_t count = reader.get<uint64_t>("count");
        m_times.compute[r] += compute;
        m_times.loading[r] += loading;
        m_times.cases[r] += int(count);
        for (uint64_t i = 0; i < count; ++i) {
            const uint64_t c = reader.get<uint64_t>("case");
            if (c >= cases || seen[c] || m_last_owner[c] != int(r))
                throw std::runtime_error("rank " + std::to_string(r) + " returned load case " + std::to_string(c)
                    + ", which was not its to evaluate");
            seen[c] = true;
            seconds[c] = reader.get<double>("seconds");
            const uint8_t kind = reader.get<uint8_t>("outcome");
            if (kind == SHARE) {
                shares[c] = reader.string("share");
                continue;
            }
            const Failure f = get_failure(reader, kind);
            if (c < first_failed) {
                first_failed = c;
                failure = f;
            }
        }
        reader.finish();
    }
    for (size_t c = 0; c < cases; ++c)
        if (!seen[c])
            throw std::runtime_error("load case " + std::to_string(c) + " was not evaluated (rank "
                + std::to_string(m_last_owner[c]) + " did not return it)");
    if (case_cost)
        for (size_t c = 0; c < cases; ++c)
            seconds[c] = case_cost(c, seconds[c]);
    m_costs = seconds;
    if (first_failed < cases)
        rethrow(failure);
    Evaluation total;
    for (size_t c = 0; c < cases; ++c)
        ReducedFunctional::add_share(total, unpack_evaluation(shares[c]));
    J.check_sum(total, gradient, constraints);
    return total;
}

Evaluation CaseDistribution::evaluate(const ReducedFunctional& J, const VectorXd& p, bool gradient, bool constraints)
{
    if (m_mode == Mode::DRIVER && m_rank != 0)
        throw std::logic_error("CaseDistribution::evaluate: rank " + std::to_string(m_rank) + " serves rank 0");
    if (m_mode == Mode::DRIVER && m_stopped)
        throw std::logic_error("CaseDistribution::evaluate: the serving ranks were stopped");
    const Timer wall;
    std::string bytes;
    if (m_rank == 0) {
        try {
            J.check_parameters(p);
            if (m_mode == Mode::DRIVER)
                load_on_servers(J);
            bytes = request(J, p, gradient, constraints);
        } catch (...) {
            if (m_mode == Mode::DRIVER)
                throw; // the serving ranks wait for any message: nothing to tell them
            ByteWriter w;
            w.put(char(FAILED));
            put_failure(w, current_failure());
            bytes = w.bytes;
        }
    }
    m_comm->broadcast(bytes);
    if (!bytes.empty() && bytes[0] == FAILED) {
        ByteReader r { bytes, "evaluation request" };
        r.get<char>("command");
        const Failure f = get_failure(r, r.get<uint8_t>("outcome"));
        rethrow(f);
    }
    if (m_rank != 0)
        m_last_owner = read_request(bytes).owner;
    const std::string mine = evaluate_mine(&J, bytes, "");
    if (m_rank == 0 && on_wait && m_size > 1)
        on_wait(describe_assignment(m_last_owner, m_size));
    const std::vector<std::string> replies = m_comm->gather(mine);
    if (m_rank == 0 && on_wait && m_size > 1)
        on_wait("");
    ++m_times.evaluations;
    if (m_mode == Mode::DRIVER) {
        Evaluation total = combine(J, replies, gradient, constraints);
        m_times.wall += wall.seconds();
        return total;
    }
    // COLLECTIVE: rank 0 combines and sends every rank the sum or the error.
    ByteWriter result;
    if (m_rank == 0) {
        try {
            const Evaluation total = combine(J, replies, gradient, constraints);
            result.put(uint8_t(SHARE));
            result.put_string(pack_evaluation(total));
        } catch (...) {
            put_failure(result, current_failure());
        }
    }
    m_comm->broadcast(result.bytes);
    m_times.wall += wall.seconds();
    ByteReader reader { result.bytes, "evaluation result" };
    const uint8_t kind = reader.get<uint8_t>("outcome");
    if (kind != SHARE) {
        const Failure f = get_failure(reader, kind);
        reader.finish();
        rethrow(f);
    }
    Evaluation total = unpack_evaluation(reader.string("sum"));
    reader.finish();
    return total;
}

void CaseDistribution::serve()
{
    if (m_mode != Mode::DRIVER || m_rank == 0)
        throw std::logic_error("CaseDistribution::serve: only ranks > 0 of a DRIVER distribution serve");
    std::deque<uint64_t> order;
    std::map<uint64_t, std::unique_ptr<ReducedFunctional>> problems;
    std::map<uint64_t, std::string> load_errors;
    for (;;) {
        std::string message;
        m_comm->broadcast(message);
        try {
            if (message.empty())
                throw std::invalid_argument("an empty message");
            if (message[0] == STOP)
                return;
            if (message[0] == LOAD) {
                ByteReader r { message, "problem message" };
                r.get<char>("command");
                const uint64_t id = r.get<uint64_t>("id");
                const std::string document = r.string("document"), base = r.string("base_directory"),
                                  source = r.string("source"), device = r.string("device");
                r.finish();
                const Timer timer;
                try {
                    problems[id]
                        = std::make_unique<ReducedFunctional>(nlohmann::json::parse(document), base, source, device);
                } catch (const std::exception& e) {
                    load_errors[id] = "rank " + std::to_string(m_rank) + " could not load the problem: " + e.what();
                }
                m_unreported_loading += timer.seconds();
                order.push_back(id);
                while (order.size() > held_problems) {
                    problems.erase(order.front());
                    load_errors.erase(order.front());
                    order.pop_front();
                }
                continue;
            }
            if (message[0] != EVALUATE)
                throw std::invalid_argument(std::string("unknown command '") + message[0] + "'");
            const Request q = read_request(message);
            m_last_owner = q.owner;
            // The least recently evaluated problem goes first (rank 0 keeps the same order).
            const auto used = std::find(order.begin(), order.end(), q.problem);
            if (used != order.end()) {
                order.erase(used);
                order.push_back(q.problem);
            }
            const auto held = problems.find(q.problem);
            const auto error = load_errors.find(q.problem);
            const std::string reply = evaluate_mine(held == problems.end() ? nullptr : held->second.get(), message,
                error == load_errors.end() ? "" : error->second);
            m_comm->gather(reply);
            ++m_times.evaluations;
        } catch (const std::exception& e) {
            m_comm->abort("diffipc: rank " + std::to_string(m_rank) + ": " + e.what(), 3);
        }
    }
}

} // namespace diffipc
