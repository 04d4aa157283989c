#include "shape_opt/optimizer/ipopt_driver.hpp"

#include "forward/common/error.hpp"

#include <IpIpoptApplication.hpp>
#include <IpIpoptCalculatedQuantities.hpp>
#include <IpIpoptData.hpp>
#include <IpOrigIpoptNLP.hpp>
#include <IpSolveStatistics.hpp>
#include <IpTNLP.hpp>
#include <IpTNLPAdapter.hpp>

#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <deque>
#include <exception>
#include <sstream>

namespace diffipc {

namespace {

    using Ipopt::Number;
    using IpIndex = Ipopt::Index; // int; diffipc::Index is Eigen's

    const char* status_name(Ipopt::ApplicationReturnStatus status)
    {
        switch (status) {
        case Ipopt::Solve_Succeeded:
            return "Solve_Succeeded";
        case Ipopt::Solved_To_Acceptable_Level:
            return "Solved_To_Acceptable_Level";
        case Ipopt::Infeasible_Problem_Detected:
            return "Infeasible_Problem_Detected";
        case Ipopt::Search_Direction_Becomes_Too_Small:
            return "Search_Direction_Becomes_Too_Small";
        case Ipopt::Diverging_Iterates:
            return "Diverging_Iterates";
        case Ipopt::User_Requested_Stop:
            return "User_Requested_Stop";
        case Ipopt::Feasible_Point_Found:
            return "Feasible_Point_Found";
        case Ipopt::Maximum_Iterations_Exceeded:
            return "Maximum_Iterations_Exceeded";
        case Ipopt::Restoration_Failed:
            return "Restoration_Failed";
        case Ipopt::Error_In_Step_Computation:
            return "Error_In_Step_Computation";
        case Ipopt::Maximum_CpuTime_Exceeded:
            return "Maximum_CpuTime_Exceeded";
        case Ipopt::Not_Enough_Degrees_Of_Freedom:
            return "Not_Enough_Degrees_Of_Freedom";
        case Ipopt::Invalid_Problem_Definition:
            return "Invalid_Problem_Definition";
        case Ipopt::Invalid_Option:
            return "Invalid_Option";
        case Ipopt::Invalid_Number_Detected:
            return "Invalid_Number_Detected";
        case Ipopt::Unrecoverable_Exception:
            return "Unrecoverable_Exception";
        case Ipopt::NonIpopt_Exception_Thrown:
            return "NonIpopt_Exception_Thrown";
        case Ipopt::Insufficient_Memory:
            return "Insufficient_Memory";
        case Ipopt::Internal_Error:
            return "Internal_Error";
        }
        return "unknown status";
    }

    /// The StopReason of a status Ipopt ended with by itself (not through our callback).
    StopReason stop_reason(Ipopt::ApplicationReturnStatus status)
    {
        switch (status) {
        case Ipopt::Solve_Succeeded:
        case Ipopt::Solved_To_Acceptable_Level:
        case Ipopt::Feasible_Point_Found:
            return StopReason::GRADIENT_TOLERANCE;
        case Ipopt::Search_Direction_Becomes_Too_Small:
            return StopReason::X_TOLERANCE;
        case Ipopt::Infeasible_Problem_Detected:
            return StopReason::INFEASIBLE;
        case Ipopt::Maximum_Iterations_Exceeded:
            return StopReason::ITERATION_BUDGET;
        case Ipopt::Maximum_CpuTime_Exceeded:
            return StopReason::TIME_BUDGET;
        case Ipopt::Restoration_Failed:
            return StopReason::LINE_SEARCH_STALLED;
        case Ipopt::User_Requested_Stop:
            return StopReason::USER_STOP;
        default:
            return StopReason::FAILED;
        }
    }

    bool parse_number(const std::string& text, double& value)
    {
        if (text.empty())
            return false;
        char* end = nullptr;
        errno = 0;
        value = std::strtod(text.c_str(), &end);
        return end == text.c_str() + text.size() && errno == 0 && std::isfinite(value);
    }

    bool parse_integer(const std::string& text, IpIndex& value)
    {
        if (text.empty())
            return false;
        char* end = nullptr;
        errno = 0;
        const long v = std::strtol(text.c_str(), &end, 10);
        if (end != text.c_str() + text.size() || errno != 0 || v < INT_MIN || v > INT_MAX)
            return false;
        value = IpIndex(v);
        return true;
    }

    /// @brief Sets an Ipopt option from its text, read as the option's registered type.
    /// @throws InputError naming "optimizer.options.<name>" when Ipopt has no such option or
    ///         rejects the value
    void set_option(Ipopt::IpoptApplication& app, const std::string& name, const std::string& value)
    {
        const std::string field = "optimizer.options." + name;
        const Ipopt::SmartPtr<const Ipopt::RegisteredOption> option = app.RegOptions()->GetOption(name);
        if (!Ipopt::IsValid(option))
            throw InputError(field, "Ipopt 3.11 has no option \"" + name + "\" (see its options reference)");
        bool ok = false;
        std::string expected;
        switch (option->Type()) {
        case Ipopt::OT_Number: {
            double v = 0;
            ok = parse_number(value, v) && app.Options()->SetNumericValue(name, v);
            expected = "a number in the option's range";
            break;
        }
        case Ipopt::OT_Integer: {
            IpIndex v = 0;
            ok = parse_integer(value, v) && app.Options()->SetIntegerValue(name, v);
            expected = "an integer in the option's range";
            break;
        }
        case Ipopt::OT_String: {
            ok = app.Options()->SetStringValue(name, value);
            expected = "one of";
            for (const auto& s : option->GetValidStrings())
                expected += " \"" + s.value_ + "\"";
            break;
        }
        default:
            expected = "a value of a known type";
        }
        if (!ok)
            throw InputError(field, "Ipopt rejects \"" + value + "\": expected " + expected);
    }

    /// An application without console output; options are set on it before Initialize().
    Ipopt::SmartPtr<Ipopt::IpoptApplication> make_application()
    {
        return new Ipopt::IpoptApplication(/*create_console_out=*/false);
    }

    /// The problem as Ipopt's TNLP: variables x, constraints g = (c, h) with bounds
    /// (-inf, 0] and [0, 0], dense Jacobian rows.
    class IpoptProblem : public Ipopt::TNLP {
    public:
        IpoptProblem(optimizer_detail::Run& run, const VectorXd& x0, const OptimizationValues& values0,
            double lower_infinity, double upper_infinity)
            : m_run(run)
            , m_x0(x0)
            , m_mc(run.problem().inequalities())
            , m_mh(run.problem().equalities())
            , m_lower_infinity(lower_infinity)
            , m_upper_infinity(upper_infinity)
        {
            m_cache.push_back({ x0, true, values0 });
            m_gradient_x = x0;
            m_rejected_before = run.rejected();
        }

        bool get_nlp_info(
            IpIndex& n, IpIndex& m, IpIndex& nnz_jac_g, IpIndex& nnz_h_lag, IndexStyleEnum& index_style) override
        {
            n = IpIndex(m_x0.size());
            m = m_mc + m_mh;
            nnz_jac_g = m * n;
            nnz_h_lag = 0; // limited-memory Hessian
            index_style = C_STYLE;
            return true;
        }

        bool get_bounds_info(IpIndex n, Number* x_l, Number* x_u, IpIndex m, Number* g_l, Number* g_u) override
        {
            for (IpIndex i = 0; i < n; ++i) {
                x_l[i] = std::max(m_run.lower()[i], m_lower_infinity);
                x_u[i] = std::min(m_run.upper()[i], m_upper_infinity);
            }
            for (IpIndex j = 0; j < m; ++j) {
                g_l[j] = j < m_mc ? m_lower_infinity : 0.0;
                g_u[j] = 0.0;
            }
            return true;
        }

        bool get_starting_point(IpIndex n, bool init_x, Number* x, bool init_z, Number*, Number*, IpIndex,
            bool init_lambda, Number*) override
        {
            if (init_z || init_lambda)
                return false; // no multipliers to offer (warm_start_init_point is off)
            if (init_x)
                Eigen::Map<VectorXd>(x, n) = m_x0;
            return true;
        }

        bool eval_f(IpIndex n, const Number* x, bool, Number& obj_value) override
        {
            const Entry* e = lookup(n, x);
            if (!e)
                return false;
            obj_value = e->values.f;
            return true;
        }

        bool eval_grad_f(IpIndex n, const Number* x, bool, Number* grad_f) override
        {
            const Entry* e = lookup(n, x);
            if (!e)
                return false;
            Eigen::Map<VectorXd>(grad_f, n) = e->values.gradient;
            m_gradient_x = e->x;
            return true;
        }

        bool eval_g(IpIndex n, const Number* x, bool, IpIndex, Number* g) override
        {
            const Entry* e = lookup(n, x);
            if (!e)
                return false;
            for (int j = 0; j < m_mc; ++j)
                g[j] = e->values.inequality[j];
            for (int j = 0; j < m_mh; ++j)
                g[m_mc + j] = e->values.equality[j];
            return true;
        }

        bool eval_jac_g(
            IpIndex n, const Number* x, bool, IpIndex m, IpIndex, IpIndex* iRow, IpIndex* jCol, Number* values) override
        {
            if (!values) { // the structure: dense, row by row
                for (IpIndex j = 0, k = 0; j < m; ++j)
                    for (IpIndex i = 0; i < n; ++i, ++k) {
                        iRow[k] = j;
                        jCol[k] = i;
                    }
                return true;
            }
            const Entry* e = lookup(n, x);
            if (!e)
                return false;
            for (int j = 0; j < m_mc; ++j)
                for (IpIndex i = 0; i < n; ++i)
                    values[j * n + i] = e->values.inequality_jacobian(j, i);
            for (int j = 0; j < m_mh; ++j)
                for (IpIndex i = 0; i < n; ++i)
                    values[(m_mc + j) * n + i] = e->values.equality_jacobian(j, i);
            return true;
        }

        void finalize_solution(Ipopt::SolverReturn, IpIndex, const Number*, const Number*, const Number*, IpIndex,
            const Number*, const Number*, Number, const Ipopt::IpoptData*, Ipopt::IpoptCalculatedQuantities*) override
        {
        }

        bool intermediate_callback(Ipopt::AlgorithmMode mode, IpIndex iter, Number, Number, Number inf_du, Number,
            Number, Number, Number, Number, IpIndex, const Ipopt::IpoptData* ip_data,
            Ipopt::IpoptCalculatedQuantities* ip_cq) override
        {
            if (m_exception)
                return false;
            m_iterations = iter;
            if (m_run.out_of_time())
                return stop(StopReason::TIME_BUDGET,
                    "wall-time budget of " + format_number(m_run.settings().max_seconds) + " s reached");
            if (mode == Ipopt::RestorationPhaseMode)
                return true; // iterates of the feasibility problem: not reported
            const Entry* e = current_iterate(ip_data, ip_cq);
            if (!e)
                return true;
            const OptimizerSettings& settings = m_run.settings();
            const double step_norm = m_has_previous ? (e->x - m_previous_x).lpNorm<Eigen::Infinity>() : 0.0;
            const bool feasible = m_run.feasible(e->x, e->values);
            const double f_change = m_has_previous ? optimizer_detail::relative_change(m_previous_f, e->values.f) : 0;
            const bool compare = m_has_previous && feasible && m_previous_feasible;
            m_previous_x = e->x;
            m_previous_f = e->values.f;
            m_previous_feasible = feasible;
            m_has_previous = true;
            // A resumed run's iteration 0 is the iterate it continues from (moved into the
            // interior by Ipopt's bound_push where it sat on a bound), reported already.
            const int number = m_run.first_iteration() + int(iter);
            if (iter == 0 && m_run.resumed())
                return true;
            ++m_reported;
            try {
                if (!m_run.iteration(number, e->x, e->values, inf_du, step_norm))
                    return stop(StopReason::USER_STOP,
                        "stopped by the iteration callback at iteration " + std::to_string(number));
            } catch (...) {
                m_exception = std::current_exception();
                return false;
            }
            // At the edge of the valid designs Ipopt does not know the boundary: its line search
            // cuts each step at a rejected point until the steps vanish (a beam's shape: 982 of
            // 1050 trials rejected, steps of 1e-11, to the iteration budget). Five iterations
            // in a row that needed rejections and moved x by less than 1e-9 of its size end the run.
            const bool vanishing = iter > 0 && step_norm <= 1e-9 * std::max(1.0, e->x.lpNorm<Eigen::Infinity>());
            m_stalled = vanishing && m_run.rejected() > m_rejected_before ? m_stalled + 1 : 0;
            m_rejected_before = m_run.rejected();
            if (m_stalled >= STALLED_ITERATIONS)
                return stop(StopReason::LINE_SEARCH_STALLED,
                    "the steps vanished at rejected (invalid) designs: " + std::to_string(STALLED_ITERATIONS)
                        + " iterations in a row moved x by less than 1e-9 of its size ("
                        + std::to_string(m_run.rejected())
                        + " points rejected); bound or constrain the design away from invalid ones");
            if (compare && iter > 0 && settings.x_tolerance > 0 && step_norm <= settings.x_tolerance)
                return stop(StopReason::X_TOLERANCE,
                    "step inf-norm " + format_number(step_norm) + " <= x_tolerance "
                        + format_number(settings.x_tolerance));
            if (compare && iter > 0 && settings.f_tolerance > 0 && f_change <= settings.f_tolerance)
                return stop(StopReason::F_TOLERANCE,
                    "relative change of f " + format_number(f_change) + " <= f_tolerance "
                        + format_number(settings.f_tolerance));
            return true;
        }

        static constexpr int STALLED_ITERATIONS = 5;
        int m_stalled = 0; ///< consecutive iterations of vanishing steps with rejections
        int m_rejected_before = 0; ///< rejections at the previous iteration
        std::exception_ptr m_exception; ///< thrown by the problem; rethrown after Ipopt returns
        bool m_stopped = false; ///< the callback stopped Ipopt, for m_stop_reason
        StopReason m_stop_reason = StopReason::USER_STOP;
        std::string m_stop_message;
        int m_iterations = 0;
        int m_reported = 0; ///< iterates passed to problem.iteration()

    private:
        struct Entry {
            VectorXd x;
            bool valid = false;
            OptimizationValues values;
        };

        bool stop(StopReason reason, const std::string& message)
        {
            m_stopped = true;
            m_stop_reason = reason;
            m_stop_message = message;
            return false;
        }

        /// @brief The values at x from the cache, else from one evaluation.
        /// @return nullptr at an invalid point (or once the problem has thrown)
        const Entry* lookup(IpIndex n, const Number* x)
        {
            const Eigen::Map<const VectorXd> xv(x, n);
            for (const Entry& e : m_cache)
                if (e.x == xv)
                    return e.valid ? &e : nullptr;
            if (m_exception)
                return nullptr;
            Entry e;
            e.x = xv;
            try {
                e.valid = m_run.evaluate(e.x, e.values);
            } catch (...) {
                m_exception = std::current_exception();
                return nullptr;
            }
            // Ipopt asks for f, g, their derivatives at a trial point and the next ones; a few
            // entries cover the trial points of one line search and the iterate.
            if (m_cache.size() >= 8)
                m_cache.pop_front();
            m_cache.push_back(std::move(e));
            return m_cache.back().valid ? &m_cache.back() : nullptr;
        }

        /// The iterate Ipopt holds now, in the TNLP's variables, with its values.
        const Entry* current_iterate(const Ipopt::IpoptData* ip_data, Ipopt::IpoptCalculatedQuantities* ip_cq)
        {
            VectorXd x = m_gradient_x; // Ipopt evaluates the gradient at each new iterate
            if (ip_data && ip_cq) {
                auto* orig = dynamic_cast<Ipopt::OrigIpoptNLP*>(Ipopt::GetRawPtr(ip_cq->GetIpoptNLP()));
                auto* adapter = orig ? dynamic_cast<Ipopt::TNLPAdapter*>(Ipopt::GetRawPtr(orig->nlp())) : nullptr;
                if (adapter) {
                    x.resize(m_x0.size());
                    adapter->ResortX(*ip_data->curr()->x(), x.data());
                }
            }
            return lookup(IpIndex(x.size()), x.data());
        }

        optimizer_detail::Run& m_run;
        VectorXd m_x0;
        int m_mc, m_mh;
        double m_lower_infinity, m_upper_infinity;
        std::deque<Entry> m_cache;
        VectorXd m_gradient_x;
        bool m_has_previous = false, m_previous_feasible = false;
        VectorXd m_previous_x;
        double m_previous_f = 0;
    };

    /// Our mumps_mem_percent (Ipopt's default: 1000), see set_options().
    constexpr IpIndex MUMPS_MEM_PERCENT = 100;

    /// Our defaults, then settings.options over them. A resumed run has the budgets' rest:
    /// max_iterations less the iterations done, max_seconds less the time spent.
    void set_options(Ipopt::IpoptApplication& app, const optimizer_detail::Run& run, double tol)
    {
        const OptimizerSettings& settings = run.settings();
        Ipopt::OptionsList& options = *app.Options();
        options.SetStringValue("hessian_approximation", "limited-memory");
        options.SetIntegerValue("limited_memory_max_history", settings.lbfgs_memory);
        if (tol > 0)
            options.SetNumericValue("tol", tol);
        options.SetNumericValue("constr_viol_tol", std::max(settings.constraint_tolerance, 1e-14));
        options.SetIntegerValue("max_iter",
            settings.max_iterations > 0 ? std::max(0, settings.max_iterations - run.first_iteration()) : INT_MAX);
        if (settings.max_seconds > 0)
            options.SetNumericValue("max_cpu_time", std::max(run.remaining_seconds(), 1e-3));
        // Every trial point inside the bounds the user gave (a design outside them may be invalid).
        options.SetNumericValue("bound_relax_factor", 0.0);
        options.SetIntegerValue("print_level", 0);
        options.SetStringValue("sb", "yes"); // no banner
        // MUMPS's workspace: Ipopt's default, 1000% above MUMPS's estimate, makes each
        // factorization of the small KKT systems here grow the heap past malloc's trim threshold
        // and give it back after (about 4 brk calls and fresh pages per factorization): 183 ->
        // 106 us a factorization on study 405 (9 variables), 460 -> 373 us on 404 (320), see
        // docs/performance.md. Where the estimate falls short MUMPS returns INFO(1) = -8/-9 and
        // Ipopt doubles the percentage and factors again: the factors, and every iterate, stay
        // the same.
        if (Ipopt::IsValid(app.RegOptions()->GetOption("mumps_mem_percent")))
            options.SetIntegerValue("mumps_mem_percent", MUMPS_MEM_PERCENT);
        // The limited-memory Hessian's low-rank update inside the factored matrix instead of
        // Sherman-Morrison solves with each of its 2k columns after every factorization: 90
        // MUMPS solves instead of 418 in a run of study 405, Ipopt's own CPU time 0.64x there
        // and 0.47x on 401 (docs/performance.md). The iterates differ from Ipopt's default's by
        // round-off (J within 6e-12 on 401, 403, 405).
        options.SetStringValue("limited_memory_aug_solver", "extended");
        for (const auto& [name, value] : settings.options)
            set_option(app, name, value);
    }

} // namespace

void check_ipopt_options(const OptimizerSettings& settings)
{
    const Ipopt::SmartPtr<Ipopt::IpoptApplication> app = make_application();
    for (const auto& [name, value] : settings.options)
        set_option(*app, name, value);
}

OptimizerResult minimize_ipopt(optimizer_detail::Run& run, const VectorXd& x0, const OptimizationValues& values0)
{
    const OptimizerSettings& settings = run.settings();
    const double gradient_norm0 = run.initial_gradient_norm(); // the run's start, also when resumed
    const double tol = std::max(settings.gradient_tolerance, settings.relative_gradient_tolerance * gradient_norm0);

    Ipopt::SmartPtr<Ipopt::IpoptApplication> app = make_application();
    set_options(*app, run, tol);
    IpIndex print_level = 0;
    app->Options()->GetIntegerValue("print_level", print_level, "");
    if (print_level > 0) // the console journal, created only on request (Initialize sets its level)
        app->Jnlst()->AddFileJournal("console", "stdout", Ipopt::J_ITERSUMMARY);
    double lower_infinity = -1e19, upper_infinity = 1e19;
    app->Options()->GetNumericValue("nlp_lower_bound_inf", lower_infinity, "");
    app->Options()->GetNumericValue("nlp_upper_bound_inf", upper_infinity, "");

    std::istringstream no_options_file; // settings.options are the only options; ipopt.opt is not read
    if (app->Initialize(no_options_file) != Ipopt::Solve_Succeeded)
        throw InputError("optimizer.options", "Ipopt could not be initialized with these options");

    Ipopt::SmartPtr<IpoptProblem> nlp = new IpoptProblem(run, x0, values0, lower_infinity, upper_infinity);
    const Ipopt::ApplicationReturnStatus status
        = app->OptimizeTNLP(Ipopt::SmartPtr<Ipopt::TNLP>(Ipopt::GetRawPtr(nlp)));
    if (nlp->m_exception)
        std::rethrow_exception(nlp->m_exception);
    if (status == Ipopt::Invalid_Option)
        throw InputError(
            "optimizer.options", "Ipopt reports an invalid option (Invalid_Option): check the options given");
    if (status == Ipopt::Insufficient_Memory)
        throw std::bad_alloc();

    int iterations = nlp->m_iterations;
    if (Ipopt::IsValid(app->Statistics()))
        iterations = app->Statistics()->IterationCount();
    iterations += run.first_iteration();
    if (nlp->m_stopped)
        return run.finish(
            nlp->m_stop_reason, "ipopt: " + nlp->m_stop_message + " (" + status_name(status) + ")", iterations);
    std::string message = std::string("ipopt: ") + status_name(status);
    if (status == Ipopt::Solve_Succeeded || status == Ipopt::Solved_To_Acceptable_Level)
        message += " (tol " + format_number(tol > 0 ? tol : 1e-8) + ")";
    return run.finish(stop_reason(status), message, iterations);
}

} // namespace diffipc
