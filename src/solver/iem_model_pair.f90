!> Velocity Verlet's step and the next step's cell forces as one wavefront over the bands of a
!> rank's chunks (model_verlet_pair, documented at its interface in iem_model.f90;
!> docs/architecture.md "Velocity Verlet's next forces in the step's sweep"). The step sweeps
!> its bands as model_rate's evaluation does, each band's nodes taking their pass (the kick,
!> then the next step's kick and drift) once its cells are done; the next step's cells take a
!> band once the step has moved every node the band's cells reach (iem_stage_wave's need), so
!> they read the moved state from the processor's caches, where the next step's own sweep
!> would read it back from memory. Each node's values take the same operations in the same
!> order as in the two evaluations one after the other, so the results are bit for bit
!> theirs.
submodule (iem_model) iem_model_pair
  use iem_timers, only: timer_switch, t_force, t_update
  use iem_node_pass, only: accelerations_in_place
  implicit none

contains

  !> Documented at its interface in iem_model.f90.
  module procedure model_pair_fits
    fit = this%waves .and. n_state == 4 .and. this%bands%active .and. this%sum_in_acc .and. &
          this%beta == 0.0_wp .and. this%omega_cap == 0.0_wp .and. .not. this%nonlinear .and. &
          .not. this%split%active .and. lat%n_local == lat%n_owned
    if (fit) fit = this%wave%ready()
  end procedure model_pair_fits

  !> Documented at its interface in iem_model.f90.
  module procedure model_verlet_pair
    ! the prescribed dofs mended so far (as the run's pass left them, to be put back should a
    ! later node's kick not be finite)
    real(wp) :: kept(2, size(this%bc_node)), pd
    integer :: mended(size(this%bc_node)), nb, done(2), jb, js, n_mended, n, b
    logical :: stopped, timed

    nb = this%bands%n_bands()
    call model_set_loads(this, t1)
    call model_damping_arrays(this, lat)
    first_bad = 0
    n_mended = 0
    jb = 1
    js = 1
    done = 0
    stopped = .false.
    ! the wavefront: the step takes its next band at every turn, the next step's cells theirs
    ! once the step has passed the nodes they reach
    do while (done(1) < nb .or. (done(2) < nb .and. .not. stopped))
      if (done(1) < nb) then
        b = done(1) + 1
        call step_band(b)
        done(1) = b
      end if
      if (done(2) < nb .and. .not. stopped) then
        b = done(2) + 1
        if (done(1) >= this%wave%pair_need(b)) then
          call next_cells(b)
          done(2) = b
        end if
      end if
    end do
    paired = .not. stopped
    ! the sums in model_rate's order: the loads' powers, then the reactions' that enter p_ext;
    ! the mass damping powers in node order (the cells' damping power is 0 here)
    p_ext = model_external_power(this)
    p_damp = 0.0_wp
    if (this%alpha > 0.0_wp) then
      do n = 1, lat%n_owned
        p_damp = p_damp + this%pw_node(n)
      end do
    end if
  contains

    !> The step's cells of band b, then its pass over the nodes the band completes.
    subroutine step_band(b)
      integer, intent(in) :: b
      integer :: c1, k, lo, hi, j0, bad
      c1 = 1
      if (b > 1) c1 = this%bands%last_chunk(b - 1) + 1
      if (.not. ready) call this%cells(lat, lat%cells, y, acc, .true., t1, &
                                       this%wave%rows(1)%r, this%wave%slots(1), pd, &
                                       range=[c1, this%bands%last_chunk(b)])
      call timer_switch(t_force, t_update, timed)
      do k = this%bands%run_first(b), this%bands%run_first(b + 1) - 1
        lo = this%bands%runs(1, k)
        hi = this%bands%runs(2, k)
        call model_run_terms(this, lo, hi, acc, y, t1, .true., jb, js, j0, fold=dt)
        call accelerations_in_place(hi - lo + 1, this%alpha, this%mass(lo:hi), y(:, lo:hi), &
                                    acc(:, lo:hi), h, bad, dt)
        if (bad /= 0 .and. first_bad == 0) then
          first_bad = lo - 1 + bad
          call give_up()
        end if
        if (first_bad == 0) call mend(j0, jb - 1)
      end do
      if (timed) call timer_switch(t_update, t_force)
    end subroutine step_band

    !> The next step's cells of band b at the moved state, summed into acc (cleared there by
    !> the step's pass), with its own kernel rows and slots; not committed (the same forces:
    !> a commit changes only the springs' history, which elastic springs have none of, and
    !> the damage of a cell fracture has damaged, which stops the pairing: stop_next).
    subroutine next_cells(b)
      integer, intent(in) :: b
      integer :: c1
      logical :: hit
      c1 = 1
      if (b > 1) c1 = this%bands%last_chunk(b - 1) + 1
      call this%cells(lat, lat%cells, y, acc, .false., t_next + dt, this%wave%rows(2)%r, &
                      this%wave%slots(2), pd, range=[c1, this%bands%last_chunk(b)], damaged=hit)
      if (hit) call stop_next(b)
    end subroutine next_cells

    !> The next step stops with its band b evaluated: its forces taken off again (every node
    !> they reach was moved on by a finite kick, its rates then cleared by the pass to +0).
    subroutine stop_next(b)
      integer, intent(in) :: b
      stopped = .true.
      acc(:, 1:this%bands%done(this%wave%pair_need(b))) = 0.0_wp
    end subroutine stop_next

    !> iem_verlet's mend_prescribed for the dofs bc_by_node(j1..j2): their velocities at the
    !> next step's half step and, until released, their displacements u_bc + dt v; what the
    !> pass left is kept.
    subroutine mend(j1, j2)
      integer, intent(in) :: j1, j2
      integer :: j, q, l, c, bq
      real(wp) :: tm
      tm = t_next + h
      do j = j1, j2
        q = this%bc_by_node(j)
        bq = this%bc_id(q)
        if (tm >= this%bc_release(bq)) cycle
        l = this%bc_node(q)
        c = this%bc_comp(q)
        n_mended = n_mended + 1
        mended(n_mended) = q
        kept(:, n_mended) = [y(c, l), y(2 + c, l)]
        y(2 + c, l) = this%bc_velocity(c, bq)*tf_value(this%bc_tf(bq), tm)
        y(c, l) = u_bc(q) + dt*y(2 + c, l)
      end do
    end subroutine mend

    !> A node whose kick is not finite: the next step stops (stop_next), and the prescribed
    !> dofs mended so far are put back as the pass left them.
    subroutine give_up()
      integer :: i, q
      if (.not. stopped .and. done(2) > 0) call stop_next(done(2))
      stopped = .true.
      do i = 1, n_mended
        q = mended(i)
        y(this%bc_comp(q), this%bc_node(q)) = kept(1, i)
        y(2 + this%bc_comp(q), this%bc_node(q)) = kept(2, i)
      end do
      n_mended = 0
    end subroutine give_up
  end procedure model_verlet_pair
end submodule iem_model_pair
