!> The time loop of a dynamic run (run_dynamic): each step's checkpoint, repartitioning,
!> rates, guards, history sample, frame and progress in their order around the integrator's
!> step (docs/architecture.md, "Run driver and integrators").
submodule (iem_simulation) iem_simulation_dynamic
  implicit none

contains

  !> Documented at its interface in iem_simulation.f90.
  module procedure run_dynamic
    integer(i8) :: k, k_first
    real(wp) :: t, t_prev, wall0, wall_last, next_report
    logical :: diverged, accepted, sampled, framed, moves

    call report_start(this)
    ! on more than one rank each step's verdict stays on its rank, and a diverging run steps
    ! again from its origin: the checkpoint it continues from or its last one, else the
    ! initial state (docs/architecture.md, "How the ranks agree on a non-finite step")
    if (this%n_ranks > 1) this%origin = ''
    wall0 = MPI_Wtime()
    wall_last = wall0
    next_report = 0.1_wp
    t_prev = -1.0_wp
    this%w_ext = 0.0_wp
    this%w_damp = 0.0_wp
    k_first = 0
    if (this%restart%step > 0) then
      if (this%n_ranks > 1) this%origin = trim(this%cfg%run%restart)
      call load_checkpoint(this, stat, msg)
      if (stat /= 0) return
      call this%integ%resume(this%model, this%lat, this%halo, this%st, this%restart%t)
      k_first = this%restart%step
      t_prev = real(k_first - 1, wp)*this%dt
      next_report = real(floor(10.0_wp*real(k_first, wp)/real(this%n_steps, wp)) + 1, wp)/10.0_wp
      call log_info('continuing from '//trim(this%cfg%run%restart)//' at step '// &
                    itoa(k_first)//', t = '//rtoa(real(k_first, wp)*this%dt)//' s')
    end if
    this%integ%local = this%n_ranks > 1
    do k = k_first, this%n_steps
      t = real(k, wp)*this%dt
      if (k > k_first) then
        moves = k == int(this%cfg%run%repartition_step, i8) .or. balance_due(this, k)
        ! (the ranks agree before a checkpoint, a signal's poll or a repartitioning)
        if (this%integ%local .and. (checkpoint_looks(this, k, t_prev, t) .or. moves)) then
          call agree_steps(this, stat, msg)
          if (stat /= 0) return
        end if
        call checkpoint_if_due(this, k, t, t_prev, stat, msg)
        if (stat /= 0) return
        if (moves) then
          ! (the last step must stand before the state moves)
          call this%integ%settle(this%st, accepted)
          if (.not. accepted) then
            call stop_rejected(this, k, t, stat, msg)
            return
          end if
          if (k == int(this%cfg%run%repartition_step, i8)) then
            call repartition_run(this, k, stat, msg)
          else
            call balance_run(this, k, stat, msg)
          end if
          if (stat /= 0) return
        end if
      end if
      ! each node's and cell's damping work of the last steps into the exact sum, at steps
      ! that do not depend on the ranks (docs/numerics.md)
      if (mod(k, int(work_collect_steps, i8)) == 0) call this%model%collect_work(this%lat)
      ! a history sample at this step; the cells' energies only for the states one reads
      sampled = sample_due(this, k, t_prev, t)
      this%model%energies_due = sampled
      call this%integ%prepare(this%model, this%lat, this%halo, this%st, t, this%dt, k == 0)
      ! the last step stands once every rank agrees (RK4 agrees behind prepare's exchange)
      call this%integ%settle(this%st, accepted)
      if (.not. accepted) then
        call step_rejected(this, k, t, stat, msg)
        if (stat /= 0) return
      end if
      ! (and before a sample or a frame reads it)
      framed = frame_due(this, k, t_prev, t)
      if (this%integ%local .and. (sampled .or. framed)) then
        call agree_steps(this, stat, msg)
        if (stat /= 0) return
      end if
      if (sampled) then
        call record_sample(this, k, t, diverged)
        if (diverged) then
          call stop_diverged(this, k, t, stat, msg)
          return
        end if
        call energy_guard(this, k, t, stat, msg)
        if (stat /= 0) return
      end if
      if (framed) then
        call timer_start(t_output)
        call flush_history(this, stat)
        if (stat == 0) call write_frame(this, k, t, stat)
        call timer_stop(t_output)
        if (stat /= 0) then
          msg = 'writing output to '//trim(this%cfg%run%output_file)//' failed'
          return
        end if
      end if
      if (this%rank == 0) call progress(this, k, t, wall0, wall_last, next_report)
      if (k == this%n_steps) exit
      call plan_next(this, k, t)
      call this%integ%step(this%model, this%lat, this%halo, this%st, t, this%dt, this%w_ext, &
                           this%w_damp, accepted)
      if (.not. accepted) then
        call step_rejected(this, k + 1, t + this%dt, stat, msg)
        if (stat /= 0) return
      end if
      t_prev = t
    end do
    this%model%energies_due = .true.
    call flush_history(this, stat)
    if (stat /= 0) then
      msg = 'writing the history to '//trim(this%cfg%run%output_file)//' failed'
      return
    end if
    call log_info('done: '//itoa(this%n_steps)//' steps in '//rtoa(MPI_Wtime() - wall0)// &
                  ' s wall; final energy-balance error '//rtoa(this%last_balance))
    call report_performance(this, MPI_Wtime() - wall0)
  end procedure run_dynamic
end submodule iem_simulation_dynamic
